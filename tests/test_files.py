"""The shared file helpers (excavation_common.files)."""

from __future__ import annotations

from excavation_common.files import replace_marked

MARK = "<!-- bench -->"


def test_a_marked_section_is_replaced_and_the_rest_kept(tmp_path):
    doc = tmp_path / "doc.md"
    doc.write_text(f"# Title\n\nhand text\n\n{MARK}\nold table\nold note\n{MARK}\n\nmore text\n")
    replace_marked(doc, "new table\n", MARK)
    assert doc.read_text() == f"# Title\n\nhand text\n\n{MARK}\nnew table\n{MARK}\n\nmore text\n"
    replace_marked(doc, "new table", MARK)  # the same body again: the same file
    assert doc.read_text().count(MARK) == 2 and doc.read_text().count("new table") == 1


def test_a_section_without_markers_is_appended_with_them(tmp_path):
    doc = tmp_path / "doc.md"
    replace_marked(doc, "first", MARK)  # no file yet
    assert doc.read_text() == f"{MARK}\nfirst\n{MARK}\n"
    doc.write_text("# Title\n\n")
    replace_marked(doc, "table", MARK)
    assert doc.read_text() == f"# Title\n\n{MARK}\ntable\n{MARK}\n"


def test_an_end_marker_of_its_own_bounds_the_section(tmp_path):
    doc = tmp_path / "doc.md"
    end = "<!-- /bench -->"
    doc.write_text(f"a\n{MARK}\nold\n{end}\nb {MARK} c\n")
    replace_marked(doc, "new", MARK, end)
    assert doc.read_text() == f"a\n{MARK}\nnew\n{end}\nb {MARK} c\n"
    only_start = tmp_path / "half.md"
    only_start.write_text(f"a\n{MARK}\nold\n")  # an unclosed section: nothing is lost
    replace_marked(only_start, "new", MARK, end)
    assert only_start.read_text() == f"a\n{MARK}\nold\n\n{MARK}\nnew\n{end}\n"
