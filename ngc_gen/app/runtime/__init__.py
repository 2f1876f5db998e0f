"""What every command runs on: the command line (one-line errors, threads), composing configs,
the checks before torch loads, run directories, training, resuming, progress and background
rendering."""
