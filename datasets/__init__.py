"""Recipes (TOML) shipped with phyloc as ``phyloc.recipes`` (see README.md here)."""
