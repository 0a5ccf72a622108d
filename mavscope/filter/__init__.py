"""Display filters: a Wireshark-style language over the field registry, compiled once, run per frame.

    compile_filter('COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH', dialect).matches(frame)

A tokenizer (lexer.py), a recursive-descent parser to an AST (parser.py, which states the grammar), and a
compiler (compiler.py) that turns the AST into nested closures over the field registry's accessors
(mavscope.fields.registry). No `eval`. Literals are converted
once at compile time (enum names to numbers through the dialect, addresses to networks, regexes
compiled), and the payload is decoded per frame only when the filter names a payload field.

A NAME alone tests that the frame has the field (a bare message name: that the frame is that message).
A comparison on a field the frame does not have is false, `!=` included (Wireshark semantics).
Every error is a FilterError carrying the position and length of the offending text.
"""

from mavscope.filter.compiler import DisplayFilter, compile_filter
from mavscope.filter.errors import FilterError

__all__ = ["DisplayFilter", "FilterError", "compile_filter"]
