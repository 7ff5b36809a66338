"""Tetrahedral meshes: the tet distortion (:mod:`.distortion`), its metric
(:mod:`.metric`), the damped Gauss–Newton least squares (:mod:`.least_squares`), the move
(:mod:`.move`, polish :mod:`.polish`, boundary contact :mod:`.contact`) and the morph
(:mod:`.morph`, its path system :mod:`.path`)."""
