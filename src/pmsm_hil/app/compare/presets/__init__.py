"""Bundled `hil compare` presets (TOML)."""
