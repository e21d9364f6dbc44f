"""The commands the docs tell a user to type, read from the docs themselves.

Every fenced ``bash``/``sh``/``shell``/``console`` block of README.md and docs/*.md (and an
untagged block that shows ``$`` prompts: a console session, whose other lines are output) is split
into simple commands (continuation lines joined, ``$`` prompts, comments, environment
assignments, ``nice``/``time``/``timeout`` and ``.venv/bin/`` dropped). Each command is then
checked without running it (:func:`check_command`):

* one of the project's programs (``ant-*``, ``genome_info`` ...): its ``main`` is called
  with the command's arguments and stopped the moment its argument parser has accepted
  them (an unknown command or flag fails as the user would see it);
* ``python -m MODULE``: the module must be ours and, with arguments, parse them likewise;
* ``ros2 run PACKAGE EXECUTABLE``: the executable must be the package's, every ``-p
  NAME:=VALUE`` a parameter of that node, the arguments before ``--ros-args`` accepted by
  the node's own parser where it has one;
* ``make TARGET``: the target must be in the Makefile;
* a few shell builtins and system tools (``cd``, ``source``, ``export``, ``ip`` ...) pass
  unchecked.

Anything else (``git``, ``pip``, ``ray``, hardware tools) must be marked: an HTML comment
``<!-- docs-test: not run: REASON -->`` on the line before the block's fence says why the
block is not checked here.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import importlib.metadata
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SHELL_LANGS = {"bash", "sh", "shell", "console"}
MARK = re.compile(r"<!--\s*docs-test:\s*not run:\s*(.+?)\s*-->")
BUILTINS = {
    "cd", "source", ".", "export", "echo", "wait", "for", "do", "done", "then", "fi", "if",
    "ls", "cat", "mkdir", "cp", "rm", "kill", "true", "sleep", "unset", "ip",
}  # fmt: skip
WRAPPERS = {"nice": 2, "time": 0, "timeout": 1, "unshare": 1}
"""Commands that run another: how many arguments of their own to drop (``nice -n 10``)."""
OPERATORS = {"&&", "||", ";", "|", "&", "(", ")", ";;"}


class DocCommandError(AssertionError):
    """A documented command that its program refuses, or a block nothing checks."""


@dataclass(frozen=True)
class Block:
    """One fenced shell block: where it is, its text, and its mark (``None``: checked)."""

    path: Path
    line: int
    text: str
    mark: str | None

    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def doc_files() -> list[Path]:
    """README.md and every docs/*.md."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def blocks_of(path: Path, text: str | None = None) -> list[Block]:
    """The fenced shell blocks of a Markdown file, each with its mark if any."""
    text = path.read_text() if text is None else text
    lines = text.splitlines()
    out, i = [], 0
    while i < len(lines):
        m = re.match(r"^(\s*)```(\w*)\s*$", lines[i])
        if not m:
            i += 1
            continue
        lang, start = m.group(2), i
        j = i + 1
        while j < len(lines) and not re.match(r"^\s*```\s*$", lines[j]):
            j += 1
        console = any(ln.startswith("$ ") for ln in lines[start + 1 : j])
        if lang in SHELL_LANGS or (lang == "" and console):
            before = lines[start - 1] if start else ""
            mark = MARK.search(before)
            body = "\n".join(lines[start + 1 : j])
            out.append(Block(path, start + 1, body, mark.group(1) if mark else None))
        i = j + 1
    return out


def commands_of(block_text: str) -> list[list[str]]:
    """The simple commands of a block, each as its words (wrappers and prompts dropped)."""
    joined = re.sub(r"\\\n", " ", block_text)
    console = any(ln.startswith("$ ") for ln in joined.splitlines())
    out = []
    for raw in joined.splitlines():
        line = raw.strip()
        if line.startswith("$ "):
            line = line[2:]
        elif console:
            continue  # a console session: the lines without a prompt are output
        if not line or line.startswith("#"):
            continue
        lex = shlex.shlex(line, posix=True, punctuation_chars=";&|()")
        lex.whitespace_split = True
        lex.commenters = "#"
        words: list[str] = []
        for token in lex:
            if token in OPERATORS:
                if words:
                    out.append(words)
                words = []
            else:
                words.append(token)
        if words:
            out.append(words)
    return _expand([c for c in (_strip(c) for c in out) if c])


def _expand(commands: list[list[str]]) -> list[list[str]]:
    """Bind ``for VAR in A B ...; do`` loops to their first value; unwrap ``sh -c``.

    ``$VAR`` and ``${VAR}`` in later commands become that value; ``do`` before a command
    goes; ``sh -c 'A; B'`` becomes the commands A and B.
    """
    bound: dict[str, str] = {}
    out = []
    for words in commands:
        if words[0] == "for" and len(words) > 3 and words[2] == "in":
            bound[words[1]] = words[3]
            continue
        if words[0] == "do":
            words = words[1:]
        if not words or words[0] == "done":
            continue
        words = [
            re.sub(r"\$\{?(\w+)\}?", lambda m: bound.get(m.group(1), m.group(0)), w) for w in words
        ]
        if words[0] in ("sh", "bash") and words[1:2] == ["-c"] and len(words) > 2:
            out += commands_of(words[2])
            continue
        out.append(words)
    return out


def _strip(words: list[str]) -> list[str]:
    """Drop ``VAR=value`` prefixes, wrappers (``nice -n 10``) and ``.venv/bin/``."""
    while words:
        if re.match(r"^[A-Za-z_][A-Za-z0-9_]*=", words[0]):
            words = words[1:]
        elif words[0] in WRAPPERS:
            words = words[1 + WRAPPERS[words[0]] :]
        else:
            break
    if words:
        words = [re.sub(r"^(\./)?\.venv/bin/", "", words[0]), *words[1:]]
    return words


@functools.cache
def entry_points() -> dict[str, str]:
    """Console scripts of the project's packages: name -> ``module:function``."""
    eps = importlib.metadata.entry_points(group="console_scripts")
    ours = (
        "ant_evolution", "excavation", "ant_controller", "blueprint_server", "blade_driver",
        "team_", "drive_executor", "overhead_localizer", "terrain_mapper", "dome_emulator",
    )  # fmt: skip
    return {ep.name: ep.value for ep in eps if any(ep.value.startswith(p) for p in ours)}


class _Parsed(Exception):
    """Raised the moment a parser accepted the arguments."""


def parse_only(main, argv: list[str]) -> None:
    """Run ``main(argv)`` until its argument parser accepts ``argv``; never further.

    Raises:
        DocCommandError: When the parser refuses the arguments (with its message).
    """
    original, known = argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args
    depth = [0]

    def parse_args(self, args=None, namespace=None):
        depth[0] += 1
        try:
            original(self, args, namespace)
        finally:
            depth[0] -= 1
        raise _Parsed

    def parse_known_args(self, args=None, namespace=None):
        result = known(self, args, namespace)
        if depth[0] == 0:
            raise _Parsed
        return result

    def error(self, message):
        raise DocCommandError(f"{self.prog}: error: {message}")

    saved_error = argparse.ArgumentParser.error
    argparse.ArgumentParser.parse_args = parse_args
    argparse.ArgumentParser.parse_known_args = parse_known_args
    argparse.ArgumentParser.error = error
    try:
        main(argv)
    except _Parsed:
        return
    except SystemExit as e:  # --help
        if e.code not in (0, None):
            raise DocCommandError(f"exit code {e.code}") from None
        return
    finally:
        argparse.ArgumentParser.parse_args = original
        argparse.ArgumentParser.parse_known_args = known
        argparse.ArgumentParser.error = saved_error
    raise DocCommandError("the program returned without parsing its arguments")


def _load(value: str):
    module, _, func = value.partition(":")
    return getattr(importlib.import_module(module), func)


def _uses_argparse(module: str) -> bool:
    spec = importlib.util.find_spec(module)
    return spec is not None and spec.origin and "argparse" in Path(spec.origin).read_text()


def make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text()
    return set(re.findall(r"^([A-Za-z][\w-]*):", text, re.M))


def node_params(package: str, executable: str) -> set[str] | None:
    """Parameter names of the node ``ros2 run PACKAGE EXECUTABLE`` starts (None: not a node)."""
    from excavation_bringup.kinds import KINDS
    from excavation_common.params import specs

    for kind in KINDS.values():
        if kind.package == package and kind.executable == executable:
            names: set[str] = set()
            for ref in kind.params:
                mod, _, cls = ref.partition(":")
                names |= set(specs(getattr(importlib.import_module(mod), cls)))
            return names
    return None


def check_command(words: list[str]) -> str:
    """Check one documented command; returns what was checked.

    Raises:
        DocCommandError: When it is refused, or is no command this checker knows.
    """
    eps = entry_points()
    tool, args = words[0], words[1:]
    if tool in eps:
        parse_only(_load(eps[tool]), args)
        return f"parsed by {tool}"
    if tool in ("python", "python3") and args[:1] == ["-m"] and len(args) > 1:
        module, rest = args[1], args[2:]
        if importlib.util.find_spec(module) is None:
            raise DocCommandError(f"python -m {module}: no such module")
        if rest and _uses_argparse(module):
            parse_only(importlib.import_module(module).main, rest)
            return f"parsed by python -m {module}"
        return f"module {module} exists"
    if tool == "ros2" and args[:1] == ["run"]:
        return _check_ros2_run(args[1:], eps)
    if tool == "make":
        missing = [a for a in args if not a.startswith("-") and "=" not in a]
        missing = [a for a in missing if a not in make_targets()]
        if missing:
            raise DocCommandError(f"make {missing[0]}: no such target in the Makefile")
        return "make targets exist"
    if tool in BUILTINS:
        return "shell builtin"
    raise DocCommandError(f"{tool}: not a program of this project (mark the block)")


def _check_ros2_run(args: list[str], eps: dict[str, str]) -> str:
    if len(args) < 2:
        raise DocCommandError("ros2 run needs PACKAGE EXECUTABLE")
    package, exe, rest = args[0], args[1], args[2:]
    if exe not in eps or not eps[exe].startswith(package + "."):
        raise DocCommandError(f"ros2 run {package} {exe}: no such executable in {package}")
    own = rest[: rest.index("--ros-args")] if "--ros-args" in rest else rest
    ros = rest[len(own) + 1 :] if "--ros-args" in rest else []
    params = node_params(package, exe)
    if params is None:
        parse_only(_load(eps[exe]), own)
        return "parsed by the program"
    names = [ros[i + 1].split(":=")[0] for i, a in enumerate(ros[:-1]) if a == "-p"]
    unknown = [n for n in names if n not in params | {"use_sim_time"}]  # every node has it
    if unknown:
        raise DocCommandError(f"ros2 run {package} {exe}: no parameter {unknown[0]!r}")
    module = importlib.import_module(eps[exe].partition(":")[0])
    if own:
        parser = getattr(module, "parse_args", None)
        if parser is None:
            raise DocCommandError(f"ros2 run {package} {exe}: takes no arguments {own}")
        try:
            parser(own)
        except SystemExit as e:
            raise DocCommandError(f"ros2 run {package} {exe} {own}: refused") from e
    return "node parameters exist"


def shown_errors(block_text: str) -> dict[str, str]:
    """A console session's commands whose shown output is a refusal: command -> message.

    The line after ``$ COMMAND`` reading ``PROGRAM: error: MESSAGE``.
    """
    lines = block_text.splitlines()
    out = {}
    for here, after in zip(lines, lines[1:], strict=False):
        m = re.match(r"^[\w.-]+: error: (.*)$", after)
        if here.startswith("$ ") and m:
            out[here[2:].strip()] = m.group(1)
    return out


def check_block(block: Block) -> int:
    """Check every command of an unmarked block; returns how many were checked.

    A command a console session shows being refused may be refused here too, with the
    message shown (or accepted: the refusal then comes after the parser, at run time).

    Raises:
        DocCommandError: Naming the block, the command and the reason.
    """
    refusals = {tuple(commands_of(k)[0]): v for k, v in shown_errors(block.text).items()}
    commands = commands_of(block.text)
    if not commands:
        raise DocCommandError(f"{block.where()}: a shell block with no command")
    for words in commands:
        try:
            check_command(words)
        except DocCommandError as e:
            shown = refusals.get(tuple(words))
            if shown is None or shown not in str(e):
                raise DocCommandError(f"{block.where()}: `{' '.join(words)}`: {e}") from None
    return len(commands)
