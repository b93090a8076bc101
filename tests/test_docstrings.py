"""Every Examples section of the public API runs and prints what it says."""

import doctest
import importlib
import pkgutil
import tempfile

import numpy as np
import pytest

import hyperlf

# the package itself too: walk_packages lists only what is below it, so the examples of the
# top-level functions (hyperlf.load, hyperlf.depth, ...) never ran before
MODULES = ["hyperlf"] + sorted(
    m.name for m in pkgutil.walk_packages(hyperlf.__path__, "hyperlf.")
    if not m.name.rsplit(".", 1)[-1].startswith("_"))


def test_the_public_modules_are_found():
    assert {"hyperlf", "hyperlf.costs", "hyperlf.regularisers", "hyperlf.hlf",
            "hyperlf.warp"} <= set(MODULES)


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


def _readme_python() -> list[str]:
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    return [block.split("```", 1)[0] for block in text.split("```python\n")[1:]]


def test_the_readmes_python_runs_and_scores_its_map(tmp_path, monkeypatch, capsys):
    """The README's Python example, as a new user pastes it: it runs, and the default depth
    of its procedural scene scores as that scene should (RMSE under 0.5 px)."""
    blocks = _readme_python()
    assert blocks, "the README has no Python example"
    monkeypatch.chdir(tmp_path)
    scope = {}
    for block in blocks:
        exec(compile(block, "README.md", "exec"), scope)
    assert scope["metrics"].hci_scores(scope["res"].disparity,
                                       scope["lf"].reference_gt_disparity).rmse < 0.5
    assert scope["done"].cube.shape[:3] == (*scope["lf"].grid_shape, scope["lf"].n_views)
    assert "DisparityScores(rmse=" in capsys.readouterr().out


#: numpydoc's order of a docstring's sections (those this project uses).
_SECTIONS = ("Parameters", "Attributes", "Returns", "Yields", "Other Parameters", "Raises",
             "Warns", "Warnings", "See Also", "Notes", "References", "Examples")


def _sections(doc: str) -> list[str]:
    """The numpydoc section titles of ``doc``, in the order they come (a title underlined)."""
    lines = [line.strip() for line in doc.splitlines()]
    return [a for a, b in zip(lines, lines[1:]) if a in _SECTIONS and b and set(b) == {"-"}]


def test_docstring_sections_come_in_numpydoc_order():
    """Examples last, Raises after Returns, ...: readers and doc tools find a section where
    numpydoc puts it (two docstrings had Examples or Returns out of place)."""
    import ast
    from pathlib import Path

    wrong = []
    for path in sorted((Path(hyperlf.__file__).parent).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                found = [_SECTIONS.index(s) for s in _sections(ast.get_docstring(node) or "")]
                if found != sorted(found):
                    wrong.append(f"{path.name}:{node.name}")
    assert not wrong, wrong
