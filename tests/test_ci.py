"""CI runs the README's test command character for character, so a step the README leaves out fails CI too.

``.ci/run`` starts with the README's test command (the line of the README's first bash
block that runs pytest, without its comment), install included, and only then installs
the other extras for its remaining checks. These tests fail when the two drift apart.
"""

from __future__ import annotations

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent


def _without_comment(line: str) -> str:
    """The shell line up to its comment: a ``#`` outside quotes, at the start or after a blank."""
    quote = None
    for position, char in enumerate(line):
        if quote:
            quote = None if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (position == 0 or line[position - 1].isspace()):
            return line[:position].strip()
    return line.strip()


def readme_test_command(readme: str) -> str:
    """The README's test command: the one line of its first bash block that runs pytest."""
    blocks = re.findall(r"^```bash\n(.*?)^```", readme, flags=re.S | re.M)
    if not blocks:
        raise ValueError("the README has no bash block")
    commands = [_without_comment(line) for line in blocks[0].splitlines()]
    testing = [command for command in commands if "pytest" in command]
    if len(testing) != 1:
        raise ValueError(f"the README's first bash block has {len(testing)} lines that run pytest, not one")
    return testing[0]


def ci_command_lines(script: str) -> list[str]:
    """The commands of a shell script, one per line, each taken out of a ``( ... )`` subshell.

    ``.ci/run`` runs the README's command in a subshell: under ``set -e`` a failure
    before the last ``&&`` of a bare line would not stop the script, a subshell's does.
    """
    lines = [_without_comment(line) for line in script.splitlines()]
    return [re.sub(r"^\(\s*(.*?)\s*\)$", r"\1", line) for line in lines if line]


def drift(readme: str, script: str) -> str | None:
    """Why ``script`` does not run the README's test command as written, or None when it does."""
    command = readme_test_command(readme)
    commands = ci_command_lines(script)
    if command not in commands:
        return f"no command line of .ci/run is the README's test command {command!r}"
    installs_first = [line for line in commands[: commands.index(command)] if "pip install" in line]
    if installs_first:
        return f".ci/run runs {installs_first[0]!r} before the README's command, which then cannot miss a package"
    return None


README = """\
# project

```bash
python3 -m pip install -e . && tool run       # the main job
python3 -m pip install -e ".[test]" && python3 -m pytest -q   # the tests (what .ci/run runs)
```
"""

SCRIPT = """\
#!/usr/bin/env bash
set -euo pipefail
cd "$(dirname "$0")/.."
( python3 -m pip install -e ".[test]" && python3 -m pytest -q )
python3 -m pip install -q -e ".[docs,dev]"
python3 -m ruff check .
"""


def test_ci_runs_the_readmes_test_command():
    readme = (ROOT / "README.md").read_text()
    assert drift(readme, (ROOT / ".ci" / "run").read_text()) is None
    assert readme_test_command(readme) == 'python3 -m pip install -e ".[test]" && python3 -m pytest -q'


def test_a_matching_pair_passes():
    assert readme_test_command(README) == 'python3 -m pip install -e ".[test]" && python3 -m pytest -q'
    assert drift(README, SCRIPT) is None
    assert drift(README, SCRIPT.replace("( ", "").replace(" )", "")) is None, "a bare line is the command too"


@pytest.mark.parametrize(
    "script",
    [
        # CI installs more than the README tells a reader to
        SCRIPT.replace('".[test]" && python3 -m pytest', '".[test,docs,dev]" && python3 -m pytest'),
        # CI runs the tests with other options
        SCRIPT.replace("pytest -q )", "pytest -q -n 2 )"),
        # the README's command is there, commented out
        SCRIPT.replace("( python3 -m pip", "# ( python3 -m pip"),
        # the README's command, but after the other extras were installed
        SCRIPT.replace('( python3 -m pip install -e ".[test]" && python3 -m pytest -q )\n', "")
        + '( python3 -m pip install -e ".[test]" && python3 -m pytest -q )\n',
    ],
    ids=["more-extras", "other-options", "commented-out", "after-other-installs"],
)
def test_a_drifted_script_is_caught(script):
    assert drift(README, script) is not None


def test_a_changed_readme_command_is_caught():
    readme = README.replace("pytest -q   #", "pytest -q -x   #")
    assert readme_test_command(readme) == 'python3 -m pip install -e ".[test]" && python3 -m pytest -q -x'
    assert drift(readme, SCRIPT) is not None


def test_a_hash_inside_quotes_is_not_a_comment():
    assert _without_comment('echo "a # b" # note') == 'echo "a # b"'
    assert _without_comment("pytest -k 'x#y'") == "pytest -k 'x#y'"
