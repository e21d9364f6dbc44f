"""Every command the docs show is checked against its program (docs as tests, tier one).

tests/helpers/doc_commands.py reads the fenced shell blocks of README.md and docs/*.md; each
command goes through its program's own argument parser without running, and a block that
holds anything else must say why it is not checked here.
"""

from __future__ import annotations

import pytest
from helpers.doc_commands import (
    ROOT,
    DocCommandError,
    blocks_of,
    check_block,
    check_command,
    commands_of,
    doc_files,
)

BLOCKS = [b for path in doc_files() for b in blocks_of(path)]


def test_the_docs_have_shell_blocks():
    assert len(BLOCKS) > 30


@pytest.mark.parametrize("block", BLOCKS, ids=[b.where() for b in BLOCKS])
def test_every_documented_command_is_accepted_or_its_block_marked(block):
    if block.mark is not None:
        assert len(block.mark) > 8, f"{block.where()}: say why the block is not run"
        return
    try:
        check_block(block)
    except DocCommandError as e:
        pytest.fail(str(e))


def test_a_flag_that_does_not_exist_fails():
    with pytest.raises(DocCommandError, match="unrecognized arguments: --no-such-flag"):
        check_command(["ant-trial", "--hand-coded", "--no-such-flag"])
    with pytest.raises(DocCommandError, match="invalid choice"):
        check_command(["ant-bag", "recrod", "--out", "x"])
    with pytest.raises(DocCommandError, match="no parameter 'robot'"):
        check_command(["ros2", "run", "excavation_sim", "sim", "--ros-args", "-p", "robot:=4"])
    with pytest.raises(DocCommandError, match="no such target"):
        check_command(["make", "tset"])


def test_an_unmarked_block_of_another_program_fails_and_a_marked_one_passes(tmp_path):
    text = "```bash\nray start --head\n```\n\n<!-- docs-test: not run: needs a cluster -->\n"
    text += "```bash\nray start --head\n```\n"
    first, second = blocks_of(ROOT / "README.md", text)
    assert first.mark is None and second.mark == "needs a cluster"
    with pytest.raises(DocCommandError, match="ray: not a program of this project"):
        for words in commands_of(first.text):
            check_command(words)


def test_commands_are_split_as_a_shell_would():
    text = "$ nice -n 10 .venv/bin/ant-eval --hand-coded \\\n  --robots 2 && echo done # note\n"
    assert commands_of(text) == [["ant-eval", "--hand-coded", "--robots", "2"], ["echo", "done"]]


def test_a_refusal_the_docs_show_must_be_the_one_the_program_gives():
    shown = "```\n$ ant-evolve --out r --population 100000000\nant-evolve: error: {}\n```\n"
    good = blocks_of(ROOT / "README.md", shown.format("argument --population: 100000000 is"))
    assert check_block(good[0]) == 1
    bad = blocks_of(ROOT / "README.md", shown.format("population too large"))
    with pytest.raises(DocCommandError, match="outside 2..10000"):
        check_block(bad[0])
