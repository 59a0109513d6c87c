"""Metric scale: every person at their size. `metric` scales each track (a given height, the
floor, the pose model's size) over `stature` (a skeleton's height from its bones, its stance),
`heights` (the heights the user knows) and `lens` (the focal length from the people)."""
