"""Several recordings of one scene -> one fused recording: association, sync, the rig (given, or
consensus then bundle adjustment), left/right, fusion. One stage per module, over the types of
`observations`; `fuse.fuse_recordings` calls them in order."""
