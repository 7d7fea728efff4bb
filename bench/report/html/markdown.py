"""Markdown to HTML for ``bench report``: the harness's own markdown (tables, their captions,
headings, lists, inline code) as HTML, every character of the text escaped first and only the
harness's marks (``**`` bold best, ``<u>`` underlined second, backticks) turned into tags around
the escaped text, so a name from data can never become markup."""

from __future__ import annotations

import html
import re


def esc(text) -> str:
    """HTML-escaped text (quotes included): every string from data or configuration."""
    return html.escape(str(text), quote=True)


_BOLD = re.compile(r"\*\*(.+?)\*\*")
_UNDER = re.compile(r"&lt;u&gt;(.+?)&lt;/u&gt;")
_CODE = re.compile(r"`([^`]+)`")
_NUMBER = re.compile(r"^[-+]?[\d.]+(e[-+]?\d+)?( / [-+]?[\d.]+(e[-+]?\d+)?)?( \[\d+ thr\.\])?$")


#: markdown's escapes (``bench.report.tables.model.md_escape``): a backslash before punctuation and
#: HTML's character entities stand for that character as text, never for a mark
_LITERAL = re.compile(r"\\([!-/:-@\[-`{-~])|&(amp|lt|gt|quot|#39);")
_HELD = re.compile("\x00(\\d+)\x00")


def inline(text: str) -> str:
    """One markdown cell or line as HTML: markdown's escapes (``\\*``, ``&lt;``) held as literal
    characters, everything escaped, then the harness's own marks (``**`` bold, ``<u>``
    underline, backticks) turned into tags around the escaped text."""
    held: list[str] = []

    def hold(m: re.Match) -> str:
        held.append(m.group(1) if m.group(1) is not None else html.unescape(m.group(0)))
        return f"\x00{len(held) - 1}\x00"

    out = esc(_LITERAL.sub(hold, str(text).replace("\x00", "")))
    out = _CODE.sub(r"<code>\1</code>", out)
    out = _BOLD.sub(r"<strong>\1</strong>", out)
    out = _UNDER.sub(r"<u>\1</u>", out)
    return _HELD.sub(lambda m: esc(held[int(m.group(1))]), out)


def _split_row(line: str) -> list[str]:
    body = line.strip()
    body = body[1:] if body.startswith("|") else body
    body = body[:-1] if body.endswith("|") else body
    return [c.strip() for c in body.split(" | ")] if " | " in body or body else [""]


def _is_rule(line: str) -> bool:
    return bool(re.fullmatch(r"\|?(\s*:?-{3,}:?\s*\|)+\s*:?(-{3,}:?)?\s*\|?", line.strip()))


def _plain(cell: str) -> str:
    return re.sub(r"\*\*|</?u>", "", cell).strip()


def _td(cell: str) -> str:
    num = ' class="num"' if _NUMBER.match(_plain(cell)) else ""
    return f"<td{num}>{inline(cell)}</td>"


#: a sentence (or clause) boundary in a caption: a period or semicolon, then a space and a
#: capital or an opening mark
_SENTENCE = re.compile(r"(?<=[.;])\s+(?=[A-Z\[(\"*])")
#: caption sentences shorter than this are said again (they are specific, not shared notes)
_SHARED_MIN_CHARS = 40


class PageNotes:
    """The caption sentences already shown on one page, each with the title of the table it
    was first shown under: a later caption keeps its own sentences and refers to the first
    table for the shared ones (the marking rule, the time, seed and interval notes), so the
    long shared notes are read once per page, not under every table."""

    def __init__(self) -> None:
        self.first: dict[str, str] = {}

    def shorten(self, text: str, where: str) -> str:
        """``text`` (a caption paragraph of the table titled ``where``) without the sentences
        an earlier table of the page showed, and one sentence saying where they are."""
        if re.match(r"^\[\d+\] ", text):
            return text  # a footnote: always specific to its table
        keep, shown_under = [], []
        for sentence in _SENTENCE.split(text):
            key = " ".join(sentence.split())
            earlier = self.first.get(key)
            if len(key) >= _SHARED_MIN_CHARS and earlier is not None and earlier != where:
                shown_under.append(earlier)
                continue
            self.first.setdefault(key, where)
            keep.append(sentence)
        if shown_under:
            titles = ", ".join(f'"{_md_text(t)}"' for t in dict.fromkeys(shown_under))
            keep.append(f"The other notes of this caption are given once, under {titles} "
                        "above.")
        return " ".join(keep)


def _md_text(text: str) -> str:
    return re.sub(r"([\\`*_\[\]<>|])", r"\\\1", str(text))


def markdown_html(text: str, notes: PageNotes | None = None,
                  where: str = "") -> tuple[str, int]:
    """A markdown report (the harness's tables, captions, headings and lists) as HTML, and
    the number of tables in it; with ``notes`` (one per page), a caption sentence an earlier
    table of the page showed is referred to, not repeated (``PageNotes``); ``where`` is this
    text's title."""
    lines, out, i, tables = text.splitlines(), [], 0, 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("|") and i + 1 < len(lines) and _is_rule(lines[i + 1]):
            header = _split_row(line)
            rows = []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                rows.append(_split_row(lines[i]))
                i += 1
            tables += 1
            head = "".join(f"<th>{inline(c)}</th>" for c in header)
            body = "".join("<tr>" + "".join(_td(c) for c in row) + "</tr>" for row in rows)
            out.append(f'<div class="scroll"><table><thead><tr>{head}</tr></thead>'
                       f"<tbody>{body}</tbody></table></div>")
            continue
        if line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")) + 2, 5)
            out.append(f"<h{level}>{inline(line.lstrip('#').strip())}</h{level}>")
        elif line.lstrip().startswith(("- ", "* ")):
            items = []
            while i < len(lines) and lines[i].lstrip().startswith(("- ", "* ")):
                items.append(f"<li>{inline(lines[i].lstrip()[2:])}</li>")
                i += 1
            out.append(f"<ul>{''.join(items)}</ul>")
            continue
        elif line.strip():
            para = [line.strip()]
            while i + 1 < len(lines) and lines[i + 1].strip() and not lines[i + 1].startswith(
                    ("|", "#", "- ", "* ")):
                i += 1
                para.append(lines[i].strip())
            joined = " ".join(para)
            if notes is not None:
                joined = notes.shorten(joined, where)
            out.append(f'<p class="caption">{inline(joined)}</p>')
        i += 1
    return "\n".join(out), tables
