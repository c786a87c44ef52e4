"""phyloc.localization (see DESIGN.md)."""
