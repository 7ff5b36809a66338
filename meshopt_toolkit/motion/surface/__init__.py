"""Triangle surfaces in space: the membrane distortion (:mod:`.distortion`) and bending
(:mod:`.bending`), their metric (:mod:`.metric`), the move (:mod:`.move`, on a mesh
:mod:`.mesh_move`; normal equations :mod:`.normal_equations`, polish :mod:`.polish`, fold
test and best rotations :mod:`.folds`) and the morph (:mod:`.morph`, on a mesh
:mod:`.mesh_morph`; start paths :mod:`.interpolation`, the path system
:mod:`.path_system`, contact along the path :mod:`.morph_contact`)."""
