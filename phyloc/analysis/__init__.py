"""phyloc.analysis (see DESIGN.md)."""
