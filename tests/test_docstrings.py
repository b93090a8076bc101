"""Every Examples section of the public API runs and prints what it says."""

import doctest
import importlib
import pkgutil
import tempfile

import numpy as np
import pytest

import hyperlf

MODULES = sorted(m.name for m in pkgutil.walk_packages(hyperlf.__path__, "hyperlf.")
                 if not m.name.rsplit(".", 1)[-1].startswith("_"))


def test_the_public_modules_are_found():
    assert {"hyperlf.costs", "hyperlf.regularisers", "hyperlf.hlf", "hyperlf.warp"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name, tmp_path, monkeypatch):
    # the examples' tempfile.mkdtemp() folders go into the test's own, which pytest removes
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    module = importlib.import_module(name)
    # numpy's own printing, whatever an imported package (colour-science) has set
    with np.printoptions(legacy=False):
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                                 report=True, verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
