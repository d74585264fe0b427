"""Monte-Carlo sweeps.

The sweep itself (engine), local and Ray executors (executors), the
sweep directory's Parquet store (results) and the progress bar (progress).
"""
