"""The vendored tests are not collected here: this project's tests import and run them against its own buses."""

collect_ignore_glob = ["*"]
