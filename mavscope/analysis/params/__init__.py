"""Parameters: every value a capture shows (PARAM_VALUE, PARAM_EXT_VALUE, `@PARAM/param.pck` read over
MAVLink FTP), every request to change one (PARAM_SET, PARAM_EXT_SET) with its answer, as a timeline, and
each component's final set.

`tracker.py` is the pass over the frames, `model.py` what it reports (`ParamChange`, the event the
timeline is made of), `values.py` how values are carried and written, `pck.py` the packed parameter file,
`security.py` which parameters guard the vehicle, `files.py` the `.param`/`.params` files, `export.py`
the JSON, the findings and `--diff`.
"""

from mavscope.analysis.params.export import change_json, component_json, describe, diff, param_findings, params_json
from mavscope.analysis.params.files import ParamFileError, param_file, qgc_file, read_param_text
from mavscope.analysis.params.model import Component, Param, ParamChange, ParamLog
from mavscope.analysis.params.pck import PckFile, PckParam, decode, is_param_pck
from mavscope.analysis.params.security import category, disables
from mavscope.analysis.params.tracker import CONFIRM_WINDOW, MESSAGES, ParamTracker, analyse, choose_main
from mavscope.analysis.params.values import json_value, same, value_text

__all__ = [
    "CONFIRM_WINDOW", "MESSAGES", "Component", "Param", "ParamChange", "ParamFileError", "ParamLog", "ParamTracker",
    "PckFile", "PckParam", "analyse", "category", "change_json", "choose_main", "component_json", "decode",
    "describe", "diff", "disables", "is_param_pck", "json_value", "param_file", "param_findings", "params_json",
    "qgc_file", "read_param_text", "same", "value_text",
]
