"""The glue between mavscope and its C extension `mavscope._native` (src/mavscope_native), in one place.

- `core`: the one import of the extension, the engine choice (`engine`, `available`, MAVSCOPE_PURE) and
  the contract's constants (capture kinds, transport codes), read from the extension itself. The typed
  contract of the extension is mavscope/_native.pyi.
- `table_blob`, `tables`, `summary`, `plan`: what Python compiles for C (the layout table, the summary
  table, the statistics plan) and the compiled objects kept per dialect.
- `walk` (`read -T jsonl`, summary lines), `stats`, `live`, `dump` (the accumulator read back),
  `windows` (the column-mode walk as windows of frames), `index` (the TUI's index), `columns` and
  `export` (the export's native batch source).

Nothing is imported here: importing a submodule costs only what that submodule imports.
"""
