"""Pictures of results: skeletons drawn on frames, video sinks, the fused views grid."""
