"""Detection rules as data (docs/rules.md): known MAVLink attacks, unsafe commands and the user's own, each a
display filter (the `-Y` language) with conditions on the vehicle's state, the link's signing and the
sender's history, and a threshold, in TOML files.

`model.py` the records, `loader.py` the files (every problem with its file and line), `prefilter.py` which
messages a filter can match, `state.py` what the conditions read, `engine.py` the compiled set and its run
over frames; `pack/` the shipped pack. `AuditPass(dialect, rules=...)` (mavscope.analysis.audit_pass) runs
them for every report of `audit`'s findings.
"""

from mavscope.rules.engine import RuleEngine, RuleSet, pack_rules, rule_set
from mavscope.rules.loader import PACK_DIR, RuleError, load_rules, read_file
from mavscope.rules.model import Conditions, Per, Rule, SenderState, Threshold

__all__ = ["PACK_DIR", "Conditions", "Per", "Rule", "RuleEngine", "RuleError", "RuleSet", "SenderState",
           "Threshold", "load_rules", "pack_rules", "read_file", "rule_set"]
