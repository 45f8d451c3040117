"""The per-UT candidate tables of a block of epochs: search, pruning and the table itself."""
