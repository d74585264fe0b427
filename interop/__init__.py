"""Results written for other tools.

Rerun recordings (recording; the only importer of rerun), files for navigation stacks, drawings
and trajectory evaluators (export), and the live view of a scenario being edited (watch).
"""
