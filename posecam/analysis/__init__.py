"""What the poses along a track tell: which are not a plausible person (`doubts`), the tracks
smoothed in time (`filters`), the joint angles (`angles`). Each over `results`' frames and
recordings, independent of the others."""
