"""`mavscope report`: one self-contained HTML page and a JSON document of one or more captures.

`collect.py` runs every analysis the report shows over a capture in one pass; `custody.py` is the chain
of custody (hashes, versions, dialects, key names); `summary.py` what happened, first; `model.py` the JSON
document (docs/report.md, docs/report.schema.json); `geometry.py` the map's and the plots' coordinates;
`html.py` and `template.py` the page (Jinja2, every string escaped by the template engine).
"""
