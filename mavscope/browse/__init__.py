"""Browsing a capture: a compact index of every frame (`index`) and the rows and details it hands out
(`rows`), the model of the terminal UI. No Textual here."""
