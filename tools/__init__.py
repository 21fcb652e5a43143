"""Demo and test tooling (not part of the installed library)."""
