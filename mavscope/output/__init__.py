"""Presentation of dissected frames: text (summary, tree, hex) and JSON. No terminal library here."""
