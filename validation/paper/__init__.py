"""The paper's claims reproduced.

The claim type and verdicts (claims), two-marker geometry
(geometry), the PEF, measurement cost and the planned route (pef), figures and the page.
"""
