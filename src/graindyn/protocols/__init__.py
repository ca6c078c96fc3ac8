"""What an experimentalist does: prepare a sample (insert + settle), load it, discharge it."""
