"""Developer tools: regression, A/B of two checkouts, perf map (``python -m tools.<name>``)."""
