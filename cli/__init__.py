"""jampacked.cli: the `jampacked` command line."""
