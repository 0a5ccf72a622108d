"""Subcommands of the `mavscope` command line, one module each (`register(subparsers)`)."""
