#!/usr/bin/python3
"""Checks the folders' dependency rules: every `#include "..."` of the project's C++ must
point into the including folder itself or into a folder its library may depend on.

The rules are the table under "Libraries and their dependency rules" in
docs/ARCHITECTURE.md (its input; keep the table true and this check keeps the code to it):
the `folder` column names the folders (or single files) a row owns, the `depends on`
column the libraries (in backticks) its code may include; `any` lets a row include
everything (tests, benchmarks). Exit 0 when every include keeps the rules, 1 with one line
per broken include, 2 when the table cannot be read.

    /usr/bin/python3 scripts/check_deps.py [REPO_ROOT]
"""
import re
import subprocess
import sys
from pathlib import Path

TABLE_HEADING = "## Libraries and their dependency rules"
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".inl", ".cc")
GENERATED = {"voxel.pb.h": "voxel_proto"}  # protoc output, built from proto/voxel.proto
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
TICKED = re.compile(r"`([^`]+)`")


def read_table(doc: Path):
    """Rows of the rules table: (library, [folders], set of allowed libraries or None=any)."""
    lines = doc.read_text(encoding="utf-8").splitlines()
    try:
        start = lines.index(TABLE_HEADING)
    except ValueError:
        raise SystemExit(f"check_deps: {doc}: no '{TABLE_HEADING}' section")
    rows, in_table = [], False
    for line in lines[start + 1:]:
        if not line.startswith("|"):
            if in_table:
                break
            continue
        in_table = True
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or cells[0] in ("library", "") or set(cells[0]) <= set("-: "):
            continue
        names = TICKED.findall(cells[0]) or [cells[0]]
        folders = TICKED.findall(cells[1])
        if not names or not folders:
            raise SystemExit(f"check_deps: {doc}: row without a `library` or `folder`: {line}")
        deps = cells[2]
        allowed = None if deps.strip() == "any" else set(
            d for d in TICKED.findall(deps) if d.startswith("voxel_"))
        rows.append((names[0], folders, allowed))
    if not rows:
        raise SystemExit(f"check_deps: {doc}: the rules table is empty")
    return rows


def owner_of(path: str, folder_owner):
    """The row owning a repository path: the longest folder (or file) that is a prefix."""
    best = None
    for folder, lib in folder_owner.items():
        if path == folder or path.startswith(folder.rstrip("/") + "/"):
            if best is None or len(folder) > len(best[0]):
                best = (folder, lib)
    return best[1] if best else None


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent)
    rows = read_table(root / "docs" / "ARCHITECTURE.md")
    folder_owner, allowed = {}, {}
    for lib, folders, deps in rows:
        for f in folders:
            folder_owner[f] = lib
        allowed[lib] = deps
    for lib, deps in allowed.items():
        for d in deps or ():
            if d not in allowed:
                print(f"check_deps: docs/ARCHITECTURE.md: {lib} depends on {d}, which no row defines")
                return 2

    files = subprocess.run(["git", "-C", str(root), "ls-files"], check=True, capture_output=True,
                           text=True).stdout.split()
    broken = []
    for rel in files:
        if not rel.endswith(SOURCE_SUFFIXES):
            continue
        lib = owner_of(rel, folder_owner)
        if lib is None:
            broken.append(f"{rel}: its folder is in no row of the rules table")
            continue
        text = (root / rel).read_text(encoding="utf-8", errors="replace")
        for n, line in enumerate(text.splitlines(), 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            inc = m.group(1)
            if inc in GENERATED:
                target = GENERATED[inc]
            elif (root / inc).is_file():
                target = owner_of(inc, folder_owner)
            elif (root / rel).parent.joinpath(inc).is_file():
                target = lib  # relative to the including file: its own folder
            else:
                broken.append(f"{rel}:{n}: \"{inc}\" is not a file of the repository")
                continue
            if target is None:
                broken.append(f"{rel}:{n}: \"{inc}\" is in no row of the rules table")
            elif target != lib and allowed[lib] is not None and target not in allowed[lib]:
                broken.append(f"{rel}:{n}: {lib} may not include \"{inc}\" ({target})")
    for b in broken:
        print(b)
    if broken:
        print(f"check_deps: {len(broken)} include(s) break the rules in docs/ARCHITECTURE.md")
        return 1
    print(f"check_deps: {len(files)} files, every include keeps the rules")
    return 0


if __name__ == "__main__":
    sys.exit(main())
