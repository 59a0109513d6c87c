"""Several recordings of one scene -> one fused recording: sync, association, left/right,
the rig (given, or consensus then bundle adjustment), fusion. One stage per module."""
