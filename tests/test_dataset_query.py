"""The dataset query language as a library API (`processing.io.dataset_query`), as the CLI uses it."""
from pathlib import Path

import pytest

from processing.errors import InputError
from processing.io.dataset_query import QueryError, lookup, matches, open_spec, parse_spec, select


class _Reader:
    entries = [{"activity": "walk", "direction": 1, "params": {"motion": {"kind": "file"}}},
               {"activity": "fall", "direction": 2, "params": {"motion": {"kind": "procedural"}}},
               {"activity": "walk", "direction": 3.0, "backend": "facets"}]


def test_spec_parsing_and_selection():
    path, conds = parse_spec("out/seed:direction=1|3,activity!=fall")
    assert path == Path("out/seed") and conds == [("direction", "=", ["1", "3"]), ("activity", "!=", ["fall"])]
    assert select(_Reader, conds) == [0, 2]  # 3.0 equals "3" numerically
    assert select(_Reader, parse_spec("d:params.motion.kind=file")[1]) == [0]
    assert select(_Reader, parse_spec("d:backend=none")[1]) == [0, 1]  # a missing key matches none
    assert select(_Reader, parse_spec("d:activity~FAL")[1]) == [1]
    assert lookup(_Reader.entries[0], "params.motion.kind") == "file" and lookup({}, "a.b") is None
    assert matches(_Reader.entries[1], []) and parse_spec("plain/dir") == (Path("plain/dir"), [])


def test_bad_specs_are_input_errors(tmp_path):
    with pytest.raises(QueryError, match="bad filter condition"):
        parse_spec("d:direction=1,@@=")
    with pytest.raises(InputError, match="not found|No such|index"):
        open_spec(str(tmp_path / "nothing") + ":activity=walk")
