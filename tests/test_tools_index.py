"""The index of the tools (``python -m tools``, tools/README.md) names every command there is, and only those."""

import ast
import re
import subprocess
import sys
from pathlib import Path

from tools.__main__ import COMMANDS, GROUPS, index_lines

TOOLS = Path(__file__).resolve().parent.parent / "tools"


def _is_command(path: Path) -> bool:
    """A module that runs as a command: it has an ``if __name__ == "__main__":`` block."""
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.If) and "__main__" in ast.unparse(node.test):
            return True
    return False


def test_the_index_names_every_command_and_only_commands() -> None:
    commands = {f"{p.parent.name}.{p.stem}" for group in GROUPS for p in (TOOLS / group).glob("*.py") if _is_command(p)}
    assert sorted(m for m, _, _ in COMMANDS) == sorted(commands)
    assert not [p.name for p in TOOLS.glob("*.py") if p.name != "__main__.py" and _is_command(p)]  # all in a group


def test_the_readme_holds_the_same_index() -> None:
    readme = (TOOLS / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```text\n(.*?)```", readme, re.S)
    assert [line for block in blocks for line in block.splitlines()] == index_lines()


def test_python_m_tools_prints_the_index() -> None:
    done = subprocess.run([sys.executable, "-m", "tools"], capture_output=True, text=True, check=True,
                          cwd=TOOLS.parent, timeout=60)
    assert done.stdout.splitlines() == index_lines()
