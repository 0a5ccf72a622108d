"""Every string from a capture is hostile: a STATUSTEXT, a file name moved over FTP, a parameter name and the
capture's own file name carrying HTML, script and URLs reach the page as text, never as markup. Checked on
the page's parse (html.parser): the only elements are those of the template, the one script is the
template's, no attribute is an event handler or names a URL, and each hostile string is shown escaped."""

from __future__ import annotations

import json
from html.parser import HTMLParser

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.report.template import TEMPLATE
from tests.conftest import Cli
from tests.support.builders import heartbeat_msg
from tests.support.ftpflows import GCS, VEHICLE, Flow, read_file

STATUS = "<script>fetch('http://x.test/')</script>"  # 41 bytes: STATUSTEXT.text is char[50]
STATUS2 = '"><svg onload=alert(1)><a href=//x.test>'
FILE = "/<img src=http://x.test/p onerror=alert(1)>.bin"
PARAM = b"<b>X</b>&amp;"  # char[16]
CAPTURE = "<img src=x onerror=alert(2)>'\".tlog"  # the capture file's own name
ALLOWED = {"html", "head", "meta", "title", "style", "body", "header", "h1", "h2", "h3", "p", "nav", "ul", "li", "a",
           "section", "div", "table", "thead", "tbody", "tr", "th", "td", "code", "details", "summary", "span", "b",
           "article", "svg", "rect", "polygon", "polyline", "circle", "line", "text", "g", "title", "figure", "i",
           "br", "footer", "script"}


def escaped(s: str) -> str:
    """`s` with the five characters HTML gives meaning to written as character references (as Jinja2's
    MarkupSafe writes them: &#39; and &#34; for the quotes)."""
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&#34;").replace("'", "&#39;")


class Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.attrs: list[tuple[str, str]] = []
        self.scripts: list[str] = []
        self._in_script = False
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        self.attrs += [(k, v or "") for k, v in attrs]
        self._in_script = tag == "script"

    def handle_endtag(self, tag: str) -> None:
        self._in_script = False

    def handle_data(self, data: str) -> None:
        if self._in_script:
            self.scripts.append(data)
        self.text.append(data)


@pytest.fixture(scope="module")
def page(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict]:
    tmp = tmp_path_factory.mktemp("hostile")
    flow = Flow()
    flow.send(VEHICLE, heartbeat_msg(2, 3, 1, 0, 3))
    flow.send(GCS, heartbeat_msg(6, 8))
    flow.send(VEHICLE, v2.MAVLink_statustext_message(2, STATUS.encode()))
    flow.send(VEHICLE, v2.MAVLink_statustext_message(2, STATUS2.encode()))
    flow.send(GCS, v2.MAVLink_param_set_message(1, 1, PARAM, 1.0, 9))
    flow.send(VEHICLE, v2.MAVLink_param_value_message(PARAM, 1.0, 9, 1, 0))
    read_file(flow, FILE, b"hostile bytes")
    cap = flow.write(tmp, CAPTURE)
    status, _, err = Cli()("report", str(cap), "-o", str(tmp / "r.html"), "--json", str(tmp / "r.json"))
    assert status == 0, err
    return (tmp / "r.html").read_text(encoding="utf-8"), json.loads((tmp / "r.json").read_text())


def test_hostile_strings_are_text(page: tuple[str, dict]) -> None:
    text, doc = page
    parsed = Page()
    parsed.feed(text)
    assert set(parsed.tags) <= ALLOWED, set(parsed.tags) - ALLOWED
    assert "img" not in parsed.tags and parsed.tags.count("script") == 1
    (script,) = parsed.scripts
    assert script in TEMPLATE  # the template's own, with nothing of the capture in it
    for name, value in parsed.attrs:
        assert not name.startswith("on"), (name, value)
        assert "://" not in value and not value.lower().startswith(("javascript:", "//", "data:")), (name, value)
        if name == "href":
            assert value.startswith("#"), value
    shown = "".join(parsed.text)
    for hostile in (STATUS, STATUS2, FILE, PARAM.decode(), CAPTURE):
        assert hostile in shown, hostile  # shown as the text it is...
        assert escaped(hostile) in text  # ...escaped in the source
    assert "<script>fetch" not in text and "<svg onload" not in text and "<img src" not in text
    # the JSON holds them as data
    events = doc["inputs"][0]["events"]["events"]
    assert any(STATUS in e["text"] for e in events)
    assert doc["inputs"][0]["file"]["name"] == CAPTURE
    assert [f["path"] for f in doc["inputs"][0]["files"]] == [FILE]
