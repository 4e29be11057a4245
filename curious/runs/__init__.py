"""One training run: the training loop (`Trainer`), its run folder, checkpoints, tables, and what it
checks and calls around it."""
