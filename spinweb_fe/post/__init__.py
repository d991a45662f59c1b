"""Post-processing of result files: the four-panel plot and rendered pictures and videos."""
