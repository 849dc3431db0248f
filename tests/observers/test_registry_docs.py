"""The docs' table of families is the registry's (docs/architecture.md)."""

from __future__ import annotations

import re
from pathlib import Path

from hpdob.observers import families

DOC = Path(__file__).parents[2] / "docs" / "architecture.md"


def test_the_architecture_table_lists_every_registered_family():
    rows = {}
    for line in DOC.read_text().splitlines():
        m = re.match(r"^\| `(\w+)` \| (.+?) \| (.+?) \| `(\w+|None)` \| `(\w+)` \|$", line)
        if m:
            rows[m.group(1)] = m.groups()[1:]
    assert set(rows) == {f.name for f in families()}
    for f in families():
        title, params, order, tuned = rows[f.name]
        assert title == f.title
        names = re.findall(r"`(\w+)`", params)
        assert names == list(f.keys)
        assert re.findall(r"\*\*`(\w+)`\*\*", params) == [k for k in f.keys if k in f.required]
        assert (order, tuned) == (str(f.order), f.tuned)
