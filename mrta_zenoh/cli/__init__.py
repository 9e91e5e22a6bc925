"""The `mrta` command line: a click group whose subcommands come from entry points."""
