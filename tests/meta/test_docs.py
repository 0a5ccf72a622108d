"""Every registered note and finding code is documented where a user looks it up: frame notes in
docs/json-format.md (the `notes` of a frame), capture findings in docs/analysis.md or docs/security.md."""

from __future__ import annotations

from mavscope.fields.registry import FIELDS
from mavscope.notes import CODES, Scope
from tests.conftest import ROOT


def _doc(*names: str) -> str:
    return "".join((ROOT / "docs" / n).read_text(encoding="utf-8") for n in names)


def test_frame_notes_are_in_the_json_format() -> None:
    doc = _doc("json-format.md")
    missing = [c for c, k in CODES.items() if k.scope is not Scope.CAPTURE and f"`{c}`" not in doc]
    assert not missing, f"frame note codes not in docs/json-format.md: {missing}"


def test_findings_are_in_the_analysis_or_security_docs() -> None:
    doc = _doc("analysis.md", "security.md")
    missing = [c for c, k in CODES.items() if k.scope is not Scope.FRAME and f"`{c}`" not in doc]
    assert not missing, f"finding codes in neither docs/analysis.md nor docs/security.md: {missing}"


def test_every_registered_field_is_in_the_filter_docs() -> None:
    """The field registry's header, frame, signature and encryption fields (note.<code> is documented as
    one form, payload fields come from the dialects)."""
    doc = _doc("filters.md")
    missing = [f.name for f in FIELDS if not f.name.startswith("note.") and f"`{f.name}`" not in doc]
    assert not missing, f"fields not in docs/filters.md: {missing}"
