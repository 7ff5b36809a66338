"""The Riemannian layer: metrics on the space of node positions, the exponential map
(geodesics) and retractions."""
