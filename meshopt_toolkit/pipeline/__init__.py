"""Filter API, registry, documents and pipelines (JSON and MeshLab .mlx)."""
