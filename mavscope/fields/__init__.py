"""Fields: the registry of every named field (`registry`), the detail tree built from it (`tree`) and the
Info column of a frame (`summary`)."""
