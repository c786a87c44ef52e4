"""phyloc.evaluation (see DESIGN.md)."""
