"""Speed benchmarks of the step loop (run each as ``python -m benchmarks.<name>``)."""
