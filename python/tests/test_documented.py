"""docs/python.md's worked example prints the figures the document shows."""

import contextlib
import io
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[2]


def fenced(text: str, language: str) -> list:
    return re.findall(r"```" + language + r"\n(.*?)```", text, re.S)


def numbers(text: str) -> list:
    """Every number in `text`, in order: the figures, whatever pandas' column layout."""
    return re.findall(r"-?\d+(?:\.\d+)?", text)


def test_worked_example_prints_its_documented_figures(tmp_path, monkeypatch):
    doc = (ROOT / "docs" / "python.md").read_text()
    example = fenced(doc, "python")[0]
    printed = fenced(doc, "text")[0]
    # The plot needs matplotlib, which the package does not; what it draws is printed above.
    example = example.split("# 5. A plot.")[0]
    (tmp_path / "tables").symlink_to(ROOT / "tables")
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(example, "docs/python.md", "exec"), {})
    assert numbers(out.getvalue()) == numbers(printed), out.getvalue()
