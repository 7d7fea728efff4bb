"""bench/report/html/markdown.py, in-process and fast: escaping, the harness's marks, tables,
headings, lists, captions and the page's shared caption notes (the mutants the slow page tests
left alive)."""

from html.parser import HTMLParser

from bench.report.html.markdown import PageNotes, esc, inline, markdown_html


class Tags(HTMLParser):
    """Start tags (name, attrs) and the text, in order."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data):
        self.text.append(data)


def parse(html: str) -> Tags:
    p = Tags()
    p.feed(html)
    p.close()
    return p


def test_esc_escapes_both_quotes_and_markup():
    assert esc('a"b') == "a&quot;b"
    assert esc("a'b") == "a&#x27;b"
    assert esc("<x>&") == "&lt;x&gt;&amp;"
    assert esc(3) == "3"


def test_inline_marks():
    assert inline("**1.5**") == "<strong>1.5</strong>"
    assert inline("<u>2.5</u>") == "<u>2.5</u>"
    assert inline("`a<b`") == "<code>a&lt;b</code>"
    assert inline("**a** and **b**") == "<strong>a</strong> and <strong>b</strong>"
    assert inline("<u>a</u> <u>b</u>") == "<u>a</u> <u>b</u>"
    assert inline("`a` `b`") == "<code>a</code> <code>b</code>"
    # no mark without both ends
    assert inline("**a") == "**a"
    assert inline("a``b") == "a``b"


def test_inline_markdown_escapes_are_literal():
    assert inline(r"\*\*x\*\*") == "**x**"
    assert inline(r"a\|b") == "a|b"
    assert inline(r"\`code\`") == "`code`"
    assert inline("&lt;u&gt;x&lt;/u&gt;") == "&lt;u&gt;x&lt;/u&gt;"
    assert inline("a &amp; b") == "a &amp; b"
    assert inline("&quot;q&#39;") == "&quot;q&#x27;"
    # a NUL in the text never addresses a held character
    assert inline("\x000\x00x") == "0x"
    assert inline(r"\* \_") == "* _"


def test_inline_data_never_becomes_markup():
    out = inline('<script>alert("x")</script>')
    assert "<script>" not in out
    assert out == "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;"


def table(*rows: str) -> str:
    return "\n".join(rows)


def test_table_cells_and_number_class():
    md = table("| Method | APE |", "|---|---:|", "| orb | **1.25** |", "| `x` | <u>2e-3</u> |",
               "| a | 1.5 / 2.5 |", "| b | 3 [4 thr.] |", "| c | n/a |", "| d | -7 |")
    out, n = markdown_html(md)
    assert n == 1
    p = parse(out)
    tds = [attrs for tag, attrs in p.tags if tag == "td"]
    assert [a.get("class") for a in tds] == [None, "num", None, "num", None, "num", None, "num",
                                             None, None, None, "num"]
    ths = [t for t, _ in p.tags if t == "th"]
    assert len(ths) == 2
    assert "<th>Method</th><th>APE</th>" in out
    assert "<td>orb</td>" in out
    assert '<td class="num"><strong>1.25</strong></td>' in out
    assert "<td><code>x</code></td>" in out
    assert out.startswith('<div class="scroll"><table><thead><tr>')
    assert out.endswith("</tbody></table></div>")
    assert out.count("<tr>") == 7


def test_number_pattern_edges():
    def cls(cell):
        out, _ = markdown_html(table("| h |", "|---|", f"| {cell} |"))
        return 'class="num"' in out
    assert cls("1e-3")
    assert cls("+2.5e+4")
    assert cls("1 / -2e-1")
    assert cls("1.5 [12 thr.]")
    assert not cls("1 /2")
    assert not cls("1.5 [x thr.]")
    assert not cls("e5")
    assert not cls("1.5x")
    assert not cls("x1.5")
    assert cls("<u>**3**</u>")


def test_split_row_without_outer_pipes_and_empty():
    out, n = markdown_html(table("| a | b", "|---|---|", "| 1 | 2"))
    assert n == 1
    assert "<th>a</th><th>b</th>" in out
    assert '<td class="num">1</td><td class="num">2</td>' in out
    out, _ = markdown_html(table("| a |", "|---|", "||"))
    assert "<tbody><tr><td></td></tr></tbody>" in out
    out, _ = markdown_html(table("| a|b |", "|---|", "| x|y |"))
    assert "<th>a|b</th>" in out


def test_rule_forms():
    for rule in ("|---|---|", "| :--- | ---: |", "|:---:|---|", "---|---", "|---|---"):
        out, n = markdown_html(table("| a | b |", rule, "| 1 | 2 |"))
        assert n == 1, rule
    for rule in ("|--|--|", "| a | b |", "|---x|---|"):
        out, n = markdown_html(table("| a | b |", rule))
        assert n == 0, rule
        assert "<table>" not in out


def test_table_ends_at_non_row_and_two_tables_counted():
    md = table("| a |", "|---|", "| 1 |", "text after", "", "| b |", "|---|", "| 2 |")
    out, n = markdown_html(md)
    assert n == 2
    assert '<p class="caption">text after</p>' in out
    assert out.count("<table>") == 2


def test_headings_levels():
    out, n = markdown_html("# One\n## Two\n### Three\n#### Four\n##### Five")
    assert n == 0
    assert out.split("\n") == ["<h3>One</h3>", "<h4>Two</h4>", "<h5>Three</h5>",
                               "<h5>Four</h5>", "<h5>Five</h5>"]
    assert markdown_html("#  a <b>")[0] == "<h3>a &lt;b&gt;</h3>"


def test_lists():
    out, _ = markdown_html("- a\n* **b**\n  - c\nafter")
    assert out.split("\n") == ["<ul><li>a</li><li><strong>b</strong></li><li>c</li></ul>",
                               '<p class="caption">after</p>']


def test_paragraph_joins_lines_until_structure():
    out, _ = markdown_html("one\n two \nthree\n\nfour\n# H\nfive\n- item\nsix\n| x")
    assert out.split("\n") == [
        '<p class="caption">one two three</p>', '<p class="caption">four</p>', "<h3>H</h3>",
        '<p class="caption">five</p>', "<ul><li>item</li></ul>", '<p class="caption">six</p>',
        '<p class="caption">| x</p>']
    out, _ = markdown_html("a\n* b")
    assert out.split("\n") == ['<p class="caption">a</p>', "<ul><li>b</li></ul>"]
    assert markdown_html("")[0] == ""
    assert markdown_html("\n\n")[0] == ""


LONG = "Bold marks the best value of each column in this table."  # >= 40 characters
SHORT = "Units are metres here."                                 # < 40


def test_page_notes_shared_sentence_referred_to():
    notes = PageNotes()
    first = notes.shorten(f"Specific one. {LONG}", "Table A")
    assert first == f"Specific one. {LONG}"
    second = notes.shorten(f"Other text. {LONG}", "Table B")
    assert second == ('Other text. The other notes of this caption are given once, under '
                      '"Table A" above.')
    # the same table again keeps its sentence
    assert notes.shorten(LONG, "Table A") == LONG
    # whitespace inside a sentence does not make it new
    assert notes.shorten(LONG.replace(" ", "  "), "Table C").endswith('under "Table A" above.')


def test_page_notes_short_sentences_repeat_and_footnotes():
    notes = PageNotes()
    notes.shorten(f"{SHORT} {LONG}", "A")
    assert notes.shorten(SHORT, "B") == SHORT
    assert notes.shorten(f"[1] {LONG}", "B") == f"[1] {LONG}"
    assert notes.shorten(f"Note. {LONG}", "B").endswith('under "A" above.')


def test_page_notes_boundary_40_chars():
    forty = "A" * 38 + "x."
    thirty_nine = "B" * 18 + " " + "B" * 18 + "x."  # words: its length counts one space
    assert len(forty) == 40 and len(thirty_nine) == 39
    notes = PageNotes()
    notes.shorten(f"{forty} {thirty_nine}", "A")
    assert notes.shorten(f"{forty} {thirty_nine}", "B") == (
        f'{thirty_nine} The other notes of this caption are given once, under "A" above.')


def test_page_notes_several_titles_once_each_escaped():
    long2 = "Times are wall-clock seconds on one core; see the notes."
    notes = PageNotes()
    notes.shorten(LONG, "T*1")
    notes.shorten(long2, "T*1")
    notes.shorten("Another sentence that is long enough to be shared.", "T_2")
    out = notes.shorten(f"{LONG} {long2} Another sentence that is long enough to be shared.",
                        "Z")
    assert out == r'The other notes of this caption are given once, under "T\*1", "T\_2" above.'


def test_sentence_split_points():
    notes = PageNotes()
    a = "First sentence here, long enough to count as shared."
    notes.shorten(a, "A")
    for sep, nxt in ((". ", "Next"), ("; ", "Next"), (". ", "[x]"), (". ", "(x)"),
                     (". ", '"x"'), (". ", "*x*")):
        out = notes.shorten(a[:-1] + sep.rstrip()[0:1] + " " + nxt, "B")
        if sep.startswith("."):
            assert out.startswith(nxt), (sep, nxt, out)
    # no split before a lower-case word: the whole text is one new sentence
    text = a[:-1] + ". next"
    assert notes.shorten(text, "B") == text


def test_markdown_html_with_notes_shortens_captions_and_escapes_title():
    notes = PageNotes()
    out1, _ = markdown_html(f"| a |\n|---|\n| 1 |\n{LONG}", notes, "One <b>")
    assert f'<p class="caption">{LONG}</p>' in out1
    out2, _ = markdown_html(f"{LONG}", notes, "Two")
    assert out2 == ('<p class="caption">The other notes of this caption are given once, under '
                    "&quot;One &lt;b&gt;&quot; above.</p>")
    # without notes nothing is shortened
    assert markdown_html(LONG)[0] == f'<p class="caption">{LONG}</p>'


def test_outer_pipes_without_spaces():
    out, _ = markdown_html("|ab | cd|\n|---|---|\n|1 | 22|")
    assert "<th>ab</th><th>cd</th>" in out
    assert '<td class="num">1</td><td class="num">22</td>' in out


def test_header_and_rule_at_the_end_are_a_table():
    out, n = markdown_html("| a |\n|---|")
    assert n == 1
    assert out == ('<div class="scroll"><table><thead><tr><th>a</th></tr></thead>'
                   "<tbody></tbody></table></div>")


def test_rows_are_adjacent():
    out, _ = markdown_html("| a |\n|---|\n| x |\n| y |")
    assert "<tbody><tr><td>x</td></tr><tr><td>y</td></tr></tbody>" in out


def test_heading_text_starting_with_x():
    assert markdown_html("# Xray")[0] == "<h3>Xray</h3>"
    assert markdown_html("#Xray")[0] == "<h3>Xray</h3>"


def test_indented_list_first_line_and_two_line_paragraph_at_end():
    assert markdown_html("  - a\n- b")[0] == "<ul><li>a</li><li>b</li></ul>"
    assert markdown_html("one\ntwo")[0] == '<p class="caption">one two</p>'


def test_footnote_keeps_a_shared_sentence():
    notes = PageNotes()
    notes.shorten(LONG, "A")
    assert notes.shorten(f"[2] Short. {LONG}", "B") == f"[2] Short. {LONG}"


def test_default_title_of_markdown_html_is_empty():
    notes = PageNotes()
    markdown_html(LONG, notes)
    assert notes.shorten(LONG, "B") == ("The other notes of this caption are given once, "
                                        'under "" above.')
