"""phyloc.channels (see DESIGN.md)."""
