"""The small fleets several test modules drive."""

CROSS = """
name = "cross"
seed = 3
[workspace]
size = [12.0, 12.0]
[[markers]]
id = "SW"
position = [0.0, 0.0]
height = 0.3
[[markers]]
id = "SE"
position = [12.0, 0.0]
height = 0.3
[[markers]]
id = "NE"
position = [12.0, 12.0]
height = 0.3
[[markers]]
id = "NW"
position = [0.0, 12.0]
height = 0.3
[sensor]
[robot]
[planning]
eps_max = 0.05
resolution = 0.2
[[docks]]
name = "A"
pose = [1.0, 6.0, 0.0]
[[docks]]
name = "B"
pose = [11.0, 6.0, 0.0]
[[docks]]
name = "C"
pose = [6.0, 1.0, 90.0]
[[docks]]
name = "D"
pose = [6.0, 11.0, 90.0]
[[tasks]]
from = "A"
to = "B"
[[tasks]]
from = "C"
to = "D"
[[robots]]
name = "east"
tasks = [0]
[[robots]]
name = "north"
tasks = [1]
"""
