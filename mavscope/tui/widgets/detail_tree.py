"""The detail tree of the selected frame: the items of `mavscope.mavlink.items.frame_items`.

Each node carries its `Item` (registry name, byte offset and length), which is what links the tree to
the hex view. The tree opens with the header and the payload expanded; moving to another frame keeps
the cursor on the field of the same name when the new frame has it (as Wireshark does).
"""

from __future__ import annotations

from rich.text import Text
from textual.message import Message
from textual.widgets import Tree
from textual.widgets.tree import TreeNode

from mavscope.browse.rows import Detail
from mavscope.fields.summary import frame_heading
from mavscope.fields.tree import Item
from mavscope.notes import Severity
from mavscope.tui.verdicts import BLUE, DIM, GREEN, ORANGE, RED
from mavscope.visible import printable

_STATUS_STYLE = {
    "ok": GREEN, "valid": GREEN, "bad": RED, "invalid": RED, "truncated": RED, "replay": ORANGE,
    "no-key": DIM, "decrypted": BLUE, "failed": RED, "unchecked": DIM,
}
_SEVERITY_STYLE = {Severity.ERROR.value: RED, Severity.WARN.value: ORANGE, Severity.NOTE.value: BLUE,
                   Severity.CHAT.value: DIM}
# open from the start: the header, the payload, the signature, and a container's inner protocol
EXPANDED = ("mavlink.header", "mavlink.payload", "signature", "FILE_TRANSFER_PROTOCOL.payload", "LOG_DATA.data",
            "TUNNEL.payload", "SERIAL_CONTROL.data", "ENCAPSULATED_DATA.data")


def frame_item(detail: Detail) -> Item:
    """The first line of the tree: where the frame is (generated: not a field on the wire)."""
    f = detail.frame
    return Item(frame_heading(f), "frame", 0, len(f.raw), None, (), True)


def label_of(item: Item) -> Text:
    """The node label, with verdicts in colour and generated items dimmed (a label escapes the words of the
    capture and the dialect as it is built: fields/tree.py; `printable` is the last guard)."""
    text = Text(printable(item.label))
    name = item.name
    if name in ("mavlink.crc", "signature.status", "encryption.status"):
        word = item.label.partition("[")[2] or item.label.partition(": ")[2]
        status = word.split(",")[0].split(":")[0].split("]")[0].split(" ")[0].strip()
        style = _STATUS_STYLE.get(status)
        if style:
            text.stylize(style)
    elif name.startswith("note."):
        sev = item.label[1:].partition("]")[0]
        text.stylize(_SEVERITY_STYLE.get(sev, ""))
    elif item.generated:
        text.stylize("italic")
    return text


class DetailTree(Tree[Item]):
    """The selected frame's fields."""

    DEFAULT_CSS = """
    DetailTree { padding: 0 1; }
    """

    class ItemHighlighted(Message):
        """The cursor is on `item` (None: no frame shown)."""

        def __init__(self, item: Item | None) -> None:
            super().__init__()
            self.item = item

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__("frame", id=id)
        self.show_root = False
        self.guide_depth = 3
        self.auto_expand = True
        self.detail: Detail | None = None
        self._wanted: str | None = None  # registry name of the item the user last chose

    def show(self, detail: Detail | None) -> None:
        """Show another frame's tree."""
        self.detail = detail
        self.clear()
        if detail is None:
            self.post_message(self.ItemHighlighted(None))
            return
        self._add(self.root, (frame_item(detail),) + detail.items)
        self.root.expand()
        wanted = self._wanted
        self.call_after_refresh(self._restore, wanted)

    def _add(self, parent: TreeNode[Item], items: tuple[Item, ...]) -> None:
        for it in items:
            if it.children:
                node = parent.add(label_of(it), data=it, expand=it.name in EXPANDED)
                self._add(node, it.children)
            else:
                parent.add_leaf(label_of(it), data=it)

    def _restore(self, wanted: str | None) -> None:
        node = self.find(lambda it: it.name == wanted) if wanted else None
        if node is None:
            node = self.find(lambda it: it.name == "mavlink.payload") or self.find(lambda it: True)
        if node is not None:
            self._reveal(node)
            self.move_cursor(node)
            self.post_message(self.ItemHighlighted(node.data))

    def find(self, pred) -> TreeNode[Item] | None:  # type: ignore[no-untyped-def]
        """The first node (depth first) whose item satisfies `pred`."""
        stack = list(reversed(self.root.children))
        while stack:
            node = stack.pop()
            if node.data is not None and pred(node.data):
                return node
            stack.extend(reversed(node.children))
        return None

    def _reveal(self, node: TreeNode[Item]) -> None:
        parent = node.parent
        while parent is not None:
            parent.expand()
            parent = parent.parent

    def select_byte(self, byte: int) -> Item | None:
        """Move the cursor to the most specific field covering frame byte `byte` (from the hex view)."""
        best: TreeNode[Item] | None = None
        stack = list(self.root.children)
        while stack:
            node = stack.pop()
            it = node.data
            if it is not None and it.length and it.offset <= byte < it.offset + it.length and it.name != "frame":
                if best is None or it.length <= best.data.length:  # type: ignore[union-attr]
                    best = node
            stack.extend(node.children)
        if best is None:
            return None
        self._wanted = best.data.name  # type: ignore[union-attr]
        self._reveal(best)
        self.call_after_refresh(self.move_cursor, best)
        return best.data

    def on_tree_node_highlighted(self, event: Tree.NodeHighlighted[Item]) -> None:
        event.stop()
        item = event.node.data
        if item is not None and self.has_focus:
            self._wanted = item.name
        self.post_message(self.ItemHighlighted(item))

    def on_tree_node_selected(self, event: Tree.NodeSelected[Item]) -> None:
        event.stop()
