"""phyloc.datasets (see DESIGN.md)."""
