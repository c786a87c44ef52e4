"""phyloc.network (see DESIGN.md)."""
