"""Pure camera geometry, no files: cameras and rigs, lifting to camera space, triangulation, the
floor plane."""
