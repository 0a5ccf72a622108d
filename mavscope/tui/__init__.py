"""`mavscope tui`: a Textual app over a capture (packet list, detail tree, hex; filter bar; screens).

The model is `mavscope.index.FrameIndex` (no Textual there); this package only presents it. Build the
app with `mavscope.tui.app.create_app`, which the command line and the tests both use.
"""
