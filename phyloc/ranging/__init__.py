"""phyloc.ranging (see DESIGN.md)."""
