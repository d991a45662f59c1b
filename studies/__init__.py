"""Studies that write the figures and numbers of docs/ (``python -m studies.<name>``)."""
