"""The glue between mavscope and its C extension `mavscope._native` (src/mavscope_native), in one place.

- `core`: the one import of the extension, the engine choice (`engine`, `available`, MAVSCOPE_PURE) and
  the contract's constants (capture kinds, transport codes), read from the extension itself. The typed
  contract of the extension is mavscope/_native.pyi.
- `table_blob`, `tables`, `summary`: what Python compiles for C (the layout table, the summary table)
  and the compiled objects kept per dialect.
- `walk` (`read -T jsonl`, summary lines), `live`, `windows` (the column-mode walk as windows of frames
  and FrameBatches: what `stats` and every analysis over batches read), `index` (the TUI's index),
  `columns` and `export` (the export's native batch source).

Nothing is imported here: importing a submodule costs only what that submodule imports.
"""
