"""The package reads as the pipeline: each layer imports only the layers before it (docs/architecture.md)."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "gcs_voice"
#: foundations first, then the pipeline in the order data flows, then what wires it
LAYERS = ["errors", "settings", "domain", "audio", "asr", "understanding", "actions", "link", "session", "cli"]


def _imports(layer: str) -> set[tuple[str, str]]:
    """(importing file, imported gcs_voice layer) for every import in a layer."""
    root = PACKAGE / layer
    files = sorted(root.rglob("*.py")) if root.is_dir() else [PACKAGE / f"{layer}.py"]
    found = set()
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("gcs_voice."):
                found.add((str(path.relative_to(PACKAGE)), node.module.split(".")[1]))
    return found


def test_every_module_belongs_to_a_layer():
    top = {p.stem for p in PACKAGE.iterdir()
           if (p.suffix == ".py" or (p / "__init__.py").is_file()) and not p.name.startswith("_")}
    assert top - set(LAYERS) == set(), "a new top-level module: give it a layer here and in docs/architecture.md"


@pytest.mark.parametrize("layer", LAYERS)
def test_no_layer_imports_a_later_one(layer):
    later = set(LAYERS[LAYERS.index(layer) + 1:])
    wrong = sorted((path, dst) for path, dst in _imports(layer) if dst in later)
    assert wrong == [], f"{layer} imports later layers: {wrong}"


def test_the_bridge_never_imports_the_simulator():
    offenders = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                 if any(isinstance(n, (ast.Import, ast.ImportFrom)) and "sim_bridge" in ast.unparse(n)
                        for n in ast.walk(ast.parse(p.read_text(encoding="utf-8"))))]
    assert offenders == []
