"""Capture readers: turn a file into a stream of Records. Detected by content, never by extension."""
