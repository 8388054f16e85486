"""Command-line interface of `hil`: one module per subcommand."""
