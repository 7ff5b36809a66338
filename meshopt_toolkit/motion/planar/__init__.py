"""Planar triangle meshes: the per-triangle distortion (:mod:`.distortion`), its graph
metric (:mod:`.metric`), the path energy as sparse least squares (:mod:`.path`,
:mod:`.assembly`, :mod:`.frame_blocks`, :mod:`.time_coupling`), the continuation of a
move (:mod:`.continuation`) and the morphs (:mod:`.morph`, :mod:`.scalar_morph`,
:mod:`.refinement`)."""
