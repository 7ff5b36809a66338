"""Built-in filters of meshopt-toolkit: one module per filter, named as the filter."""
