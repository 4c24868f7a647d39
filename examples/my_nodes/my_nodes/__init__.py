"""Example node package for probeless (see ../README.md)."""
