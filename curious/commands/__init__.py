"""Sub-commands of the `curious` command line, one module each."""
