"""Small utilities of the build: one BLAS thread for its many small dense solves (``blas``),
sparse products split over cores (``parallel``)."""
