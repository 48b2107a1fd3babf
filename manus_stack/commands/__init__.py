"""One module per ``manus`` subcommand that is not a service's own entry point."""
