"""The shipped category template libraries are current: their stamp matches the shipped catalog and generators."""

import json

import pytest

from ancsh.data.templates import TemplateLibrary, _stamp, library_path
from ancsh.data.procedural import CATEGORIES


@pytest.mark.parametrize("category", [c for c in CATEGORIES if library_path(c).is_file()])
def test_the_shipped_template_library_matches_the_catalog_and_the_generators(category):
    """A stale stamp makes every process rebuild the library (about 25 s), and a machine without the shared data
    loses its real templates: changing the catalog or a generator means rewriting the libraries too."""
    lib = TemplateLibrary.from_dict(json.loads(library_path(category).read_text()))
    assert lib.category == category
    assert lib.stamp == _stamp(category, lib.real)
