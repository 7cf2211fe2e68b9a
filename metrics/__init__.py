"""Point cloud quality metrics on numpy arrays."""
