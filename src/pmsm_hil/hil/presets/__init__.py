"""Motor preset files (TOML): every parameter with its value, unit and source."""
