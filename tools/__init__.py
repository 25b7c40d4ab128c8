"""Developer tools: benchmarks, the NumPy reference, README images; a package so tests can import them."""
