"""posecam: absolute 3D human poses in camera coordinates from images and videos."""

__version__ = "0.1.0"
