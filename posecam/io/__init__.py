"""What crosses the border: frames in (`media`: images, videos, folders, live sources), every
file format read and written (pose JSON/CSV, calibrations, intrinsics, TRC/C3D), the checks
each file read goes through (`validate`) and the atomic writes (`atomic`)."""
