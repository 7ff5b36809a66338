"""Tuning constants of the penalty evaluation (read at construction or call time, so a
test may patch them on this module)."""

#: boundary configurations remembered as simple by each penalty
SIMPLE_BOUNDARY_CACHE = 64

#: triangles per block of the per-triangle pass (keeps temporaries in cache)
BLOCK = 8192

#: boundary pairs evaluated at once (their derivatives take ~250 bytes per pair)
PAIR_CHUNK = 250_000

#: without a cut-off, the all-pairs list is cached when it has at most this many rows
#: (24 bytes per pair); larger sets are regenerated chunk by chunk on every call
PAIR_CACHE = 2_000_000
