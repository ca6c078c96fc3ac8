"""Studies: reproducible numerical experiments that write figures and tables."""
