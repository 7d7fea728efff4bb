"""Rules the test suite keeps about itself (HELPER-RULES / issue 25): a test that needs a dev
dependency (Open3D, rerun) or data FAILS when it is missing, it never skips; `make test` runs
every cross-check or says why not."""

import ast
from pathlib import Path

import pytest

from conftest import dev_dependency

TESTS = Path(__file__).resolve().parent
#: calls that turn a missing dependency or input into a pass
SKIPPING = {"importorskip", "skip", "skipif"}


def _skipping_calls(path: Path) -> list[str]:
    """``pytest.importorskip(...)``, ``pytest.skip(...)`` and ``pytest.mark.skip[if]`` in a
    test module (found in its syntax tree, so comments and strings do not count)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Attribute) and node.attr in SKIPPING:
            base = node.value
            names = []
            while isinstance(base, ast.Attribute):
                names.append(base.attr)
                base = base.value
            if isinstance(base, ast.Name) and base.id == "pytest":
                dotted = ".".join(["pytest", *names[::-1], node.attr])
                found.append(f"{path.name}:{node.lineno}: {dotted}")
    return found


def test_no_test_skips_for_a_missing_dependency():
    found = [hit for path in sorted(TESTS.rglob("*.py")) for hit in _skipping_calls(path)]
    assert not found, "use conftest.dev_dependency (fails) instead of skipping:\n" + \
        "\n".join(found)


def test_the_rule_check_sees_a_skip(tmp_path):
    bad = tmp_path / "test_bad.py"
    bad.write_text("import pytest\no3d = pytest.importorskip('open3d')\n"
                   "@pytest.mark.skipif(True, reason='x')\ndef test_a():\n    pytest.skip()\n"
                   "# pytest.skip in a comment does not count\n")
    assert len(_skipping_calls(bad)) == 3


def test_a_missing_dev_dependency_fails_the_test():
    with pytest.raises(pytest.fail.Exception, match="dev dependency.*make install-dev"):
        dev_dependency("a_module_that_is_not_installed")
    assert dev_dependency("open3d").__name__ == "open3d"  # installed by `make test`
