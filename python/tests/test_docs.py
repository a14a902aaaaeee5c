"""Every ```python block of docs/python.md runs as written, in order, in
one namespace, in a fresh folder holding the repository's `scenes/` (the
page says "from the repository root"): the page cannot drift from the
package again."""

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "python.md"


def blocks():
    text = PAGE.read_text()
    return [m.group(1) for m in re.finditer(r"^```python\n(.*?)^```", text, re.S | re.M)]


def test_the_page_has_python_blocks():
    assert len(blocks()) >= 3


def test_every_python_block_of_docs_python_md_runs(tmp_path, monkeypatch):
    (tmp_path / "scenes").symlink_to(ROOT / "scenes", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PRISM_ALLOW_READ", raising=False)
    namespace = {"__name__": "__docs__"}
    for i, code in enumerate(blocks()):
        try:
            exec(compile(code, f"{PAGE}:block{i}", "exec"), namespace)
        except Exception as e:  # noqa: BLE001 - name the block that failed
            pytest.fail(f"docs/python.md block {i} failed: {type(e).__name__}: {e}\n{code}")
