"""The motion engine every cell kind shares: similarities and handle paths in the plane
and in space (:mod:`.similarity`, :mod:`.similarity_3d`), the one continuation loop
(:mod:`.continuation`), the sparse pattern of per-cell blocks (:mod:`.sparse_pattern`),
the IPC contact barrier and CCD (:mod:`.contact`), the polishes' neighbourhoods and soft
maximum (:mod:`.polish`), the frames' thread pool (:mod:`.frame_threads`), handles and
targets as users give them (:mod:`.handles`, :mod:`.targets`) and the refusal of targets
that turn over cells of handles only (:mod:`.pinned_cells`)."""
