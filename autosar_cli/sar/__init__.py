"""Focusing: range compression, stripmap MIMO back-projection, tiles, and the autofocus from the radar's own echoes."""
