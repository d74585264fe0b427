"""What measurements tell.

Measurement models, fault areas (set-membership), snapshot fixes, the EKF (filterpy) and
consistency statistics. Depends only on ``scenarios``.
"""
