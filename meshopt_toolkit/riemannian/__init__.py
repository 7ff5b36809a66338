"""The Riemannian layer: metrics on the space of node positions (one ``Metric`` protocol),
the exponential and log maps, retractions and the discrete geodesic (one entry, two
methods); ARCHITECTURE.md lists where each lives."""
