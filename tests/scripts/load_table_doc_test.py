#!/usr/bin/python3
"""bench/scripts/load_table.py's --update-doc: a table replaced in docs/PERFORMANCE.md
keeps a blank line before the next section (it once ran into the slowed host's heading),
and the fast and slowed host's tables stay apart."""
import os
import sys
import unittest

sys.dont_write_bytecode = True  # nothing written into the source tree

sys.path.insert(0, os.path.join(sys.argv.pop(1) if len(sys.argv) > 1 else ".", "bench", "scripts"))
import load_table  # noqa: E402

DOC = """# Performance

Intro.

## Current figures (old, commit a)

| old |

## Current figures, slowed host (old, commit b)

| slow old |

## Journal

Text.
"""


class ReplaceSection(unittest.TestCase):
    def test_a_replaced_table_keeps_a_blank_line_before_the_next_heading(self):
        text = "## Current figures (new, commit c)\n\n| new |\n"
        doc = load_table.replace_section(DOC, "## Current figures", text)
        self.assertIn("| new |\n\n## Current figures, slowed host (old", doc)
        self.assertNotIn("| old |", doc)
        self.assertIn("| slow old |", doc)

    def test_the_slowed_hosts_table_replaces_only_its_own(self):
        text = "## Current figures, slowed host (new, commit d)\n\n| slow new |\n"
        doc = load_table.replace_section(DOC, "## Current figures, slowed host", text)
        self.assertIn("| old |\n\n## Current figures, slowed host (new", doc)
        self.assertIn("| slow new |\n\n## Journal", doc)
        self.assertNotIn("| slow old |", doc)

    def test_a_missing_section_goes_after_the_other_table(self):
        doc = DOC.replace("## Current figures, slowed host (old, commit b)\n\n| slow old |\n\n", "")
        text = "## Current figures, slowed host (new, commit d)\n\n| slow new |\n"
        doc = load_table.replace_section(doc, "## Current figures, slowed host", text)
        self.assertIn("| old |\n\n## Current figures, slowed host (new, commit d)\n\n| slow new |\n\n## Journal", doc)


if __name__ == "__main__":
    unittest.main()
