"""``python -m bench.docs_cli`` itself (its ``main``) on a page of our own: ``--check`` says
whether the page is current (exit 1 when not) and writes nothing; without it the page is
written when it changed and only then; a page changed meanwhile is left alone. Written against
the surviving mutants of ``make mutate`` on bench/docs_cli.py."""

from __future__ import annotations

from pathlib import Path

import click
import pytest

from bench import docs_cli
from loaders.errors import DataError

TEXT = "# Command reference\n\nfresh\n"


@pytest.fixture
def page(tmp_path, monkeypatch):
    """The reference page moved to a temporary folder, rendered as ``TEXT``."""
    path = tmp_path / "reference" / "commands.md"
    monkeypatch.setattr(docs_cli, "PAGE", path)
    monkeypatch.setattr(docs_cli, "render_reference", lambda: TEXT)
    return path


def test_check_of_a_current_page_is_exit_0(page, capsys):
    page.parent.mkdir()
    page.write_text(TEXT)
    assert docs_cli.main(["--check"]) == 0
    assert capsys.readouterr().out == f"{page}: up to date\n"


@pytest.mark.parametrize("old", [None, "# Command reference\n\nstale\n", ""])
def test_check_of_a_stale_or_missing_page_is_exit_1_and_writes_nothing(page, capsys, old):
    if old is not None:
        page.parent.mkdir()
        page.write_text(old)
    assert docs_cli.main(["--check"]) == 1
    assert capsys.readouterr().out == (f"{page}: out of date; run python -m bench.docs_cli "
                                       "(make docs)\n")
    assert (page.read_text() if page.exists() else None) == old


def test_check_is_read_from_the_command_line_without_arguments(page, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["docs_cli", "--check"])
    assert docs_cli.main() == 1 and not page.exists()
    assert "out of date" in capsys.readouterr().out
    monkeypatch.setattr("sys.argv", ["docs_cli"])
    assert docs_cli.main() == 0 and page.read_text() == TEXT
    # the arguments given win over the command line's
    monkeypatch.setattr("sys.argv", ["docs_cli", "--check"])
    page.write_text("stale")
    assert docs_cli.main([]) == 0 and page.read_text() == TEXT


def test_a_missing_page_is_written_with_its_folder(page, capsys):
    assert docs_cli.main([]) == 0
    assert page.read_text() == TEXT
    assert capsys.readouterr().out == f"{page}: updated\n"


def test_a_stale_page_is_replaced_and_a_current_one_left_alone(page, capsys):
    page.parent.mkdir()
    page.write_text("old text\n")
    assert docs_cli.main([]) == 0 and page.read_text() == TEXT
    assert capsys.readouterr().out == f"{page}: updated\n"
    before = page.stat().st_mtime_ns, page.stat().st_ino
    assert docs_cli.main([]) == 0
    assert capsys.readouterr().out == f"{page}: up to date\n"
    assert (page.stat().st_mtime_ns, page.stat().st_ino) == before  # not written again


class _ReadsStale(type(Path())):
    """A page path whose first read gives a stale text while the file holds another: the
    file changed between the read and the write."""

    def read_text(self, *args, **kwargs):
        return "what was read\n"


def test_a_page_changed_after_it_was_read_is_left_alone(tmp_path, monkeypatch):
    path = tmp_path / "commands.md"
    path.write_text("edited meanwhile\n")
    monkeypatch.setattr(docs_cli, "PAGE", _ReadsStale(path))
    monkeypatch.setattr(docs_cli, "render_reference", lambda: TEXT)
    with pytest.raises(DataError, match="is not the generated command reference the harness "
                                        "wrote"):
        docs_cli.main([])
    assert path.read_text() == "edited meanwhile\n"


def test_the_real_page_is_the_rendered_reference(capsys):
    """The committed page: --check through main, against the page as rendered."""
    assert docs_cli.PAGE == Path(docs_cli.__file__).resolve().parents[1] / "docs" / \
        "reference" / "commands.md"
    assert docs_cli.main(["--check"]) == 0
    assert capsys.readouterr().out.endswith(": up to date\n")


# -- the command tree and each command's section, on a small click tree of our own -------------


class _Group(click.Group):
    """A group that notes the context it is asked in (by its command path), as a group that
    lists its commands lazily would read it; ``ghost`` is listed but not found."""

    asked: list = []

    def list_commands(self, ctx):
        _Group.asked.append(("list", ctx.command_path))
        return [*super().list_commands(ctx), "ghost"]

    def get_command(self, ctx, name):
        _Group.asked.append(("get", ctx.command_path, name))
        return super().get_command(ctx, name)


def _tree():
    _Group.asked = []
    leaf = click.Command("leaf", help="A leaf.")
    hidden = click.Command("secret", help="Not listed.", hidden=True)
    sub = _Group("sub", commands=[leaf, hidden], help="A group.")
    return _Group("bench", commands=[sub, click.Command("top", short_help="Top.")])


def test_command_tree_walks_visible_commands_asking_each_group_in_its_context():
    tree = docs_cli.command_tree(_tree())
    assert list(tree) == [(), ("sub",), ("sub", "leaf"), ("top",)]
    assert tree[("sub", "leaf")].name == "leaf"
    assert ("list", "bench") in _Group.asked and ("list", "bench sub") in _Group.asked
    assert ("get", "bench", "sub") in _Group.asked
    assert ("get", "bench sub", "leaf") in _Group.asked


def test_render_command_of_a_group_lists_its_commands_in_its_context():
    root = _tree()
    sub = root.commands["sub"]
    text = docs_cli.render_command(sub, ("sub",))
    assert text.splitlines()[0] == "## `bench sub`"
    assert _Group.asked == [("list", "bench sub")]
    assert "Commands: `bench sub leaf`, `bench sub secret`, `bench sub ghost`." in text


def test_render_command_help_falls_back_to_the_short_help_and_joins_paragraphs():
    short = click.Command("top", short_help="Top only.")
    assert "Top only." in docs_cli.render_command(short, ("top",)).splitlines()
    bare = docs_cli.render_command(click.Command("bare"), ("a", "bare"))
    assert bare.splitlines()[:6] == ["### `bench a bare`", "", "```text",
                                     "bench a bare [OPTIONS]",
                                     "```", ""]
    assert bare.splitlines()[6] == "| option | what it does |"  # no help line at all
    verbatim = click.Command("v", help="First line.\n\n\b\nkept  as\n  is")
    assert "First line. kept as is" in docs_cli.render_command(verbatim, ("v",)).splitlines()


def test_render_command_arguments_without_help():
    command = click.Command("c", params=[click.Argument(["src"]), click.Argument(
        ["dst"], required=False)])
    lines = docs_cli.render_command(command, ("c",)).splitlines()
    assert "| `SRC` | required |" in lines and "| `[DST]` |  |" in lines
