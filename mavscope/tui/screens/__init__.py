"""The screens and dialogs opened from the main screen (s, m, e, k, ?)."""
