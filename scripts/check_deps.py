#!/usr/bin/python3
"""Checks docs/ARCHITECTURE.md against the tree, two ways.

1. The folders' dependency rules: every `#include "..."` of the project's C++ must point
   into the including folder itself or into a folder its library may depend on. The rules
   are the table under "Libraries and their dependency rules" (its input; keep the table
   true and this check keeps the code to it): the `folder` column names the folders (or
   single files) a row owns, the `depends on` column the libraries (in backticks) its code
   may include; `any` lets a row include everything (tests, benchmarks).

2. Every repository path the page names exists. The words looked at: each word of a
   backticked span (split at white space) and each word of a fenced code block (the
   figures). After a trailing `:LINE`, `()` or punctuation is dropped, a word names a path
   when it contains a '/' and starts with a top-level entry of the repository (a first
   component of `git ls-files`: `server/`, `docs/`, `tests/`, ...), or, in backticks only,
   when it is a bare file name ending in SOURCE_SUFFIXES or DOC_SUFFIXES. A path ending in
   '/' must be a directory, one with '*' must match a file (a glob), any other must exist.
   A bare file name passes when some tracked file has that name or it is generated
   (GENERATED, e.g. voxel.pb.h): the name alone does not say which folder is meant.
   Partial paths (`world/x.hpp`), URL paths (`/metrics`) and untracked folders (`build/`)
   are not checked.

Exit 0 when both hold; 1 with one line per broken include ("FILE:LINE: ...") and per
missing path ("docs/ARCHITECTURE.md names PATH, which does not exist"); 2 when the table
cannot be read.

    /usr/bin/python3 scripts/check_deps.py [REPO_ROOT]
"""
import fnmatch
import re
import subprocess
import sys
from pathlib import Path

TABLE_HEADING = "## Libraries and their dependency rules"
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".inl", ".cc")
DOC_SUFFIXES = (".md", ".py", ".sh", ".proto", ".txt")
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


def named_paths(text: str):
    """The words of the page that name repository paths, as (word, in_backticks), before
    the filter: backticked spans outside fenced blocks, and every word inside them."""
    words, fenced = [], False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            words += [(w, False) for w in re.findall(r"[A-Za-z0-9_.*/-]+", line)]
        else:
            for span in TICKED.findall(line):
                words += [(w, True) for w in span.split()]
    return words


def missing_paths(root: Path, doc_text: str, files):
    """The paths docs/ARCHITECTURE.md names that do not exist (see the module's rule 2)."""
    top = {f.split("/", 1)[0] for f in files}
    basenames = {f.rsplit("/", 1)[-1] for f in files} | set(GENERATED)
    missing, seen = [], set()
    for word, ticked in named_paths(doc_text):
        path = re.sub(r"(:\d+)?(\(\))?[.,;:]*$", "", word)
        if not path or path in seen:
            continue
        if "/" in path:
            if path.split("/", 1)[0] not in top:
                continue
            if "*" in path:
                ok = any(fnmatch.fnmatchcase(f, path) for f in files) or any(root.glob(path))
            elif path.endswith("/"):
                ok = (root / path).is_dir()
            else:
                ok = (root / path).exists()
        elif ticked and path.endswith(SOURCE_SUFFIXES + DOC_SUFFIXES):
            ok = any(fnmatch.fnmatchcase(b, path) for b in basenames)
        else:
            continue
        seen.add(path)
        if not ok:
            missing.append(path)
    return missing, len(seen)


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent)
    doc = root / "docs" / "ARCHITECTURE.md"
    rows = read_table(doc)
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
    missing, named = missing_paths(root, doc.read_text(encoding="utf-8"), files)
    for m in missing:
        print(f"docs/ARCHITECTURE.md names {m}, which does not exist")
    for b in broken:
        print(b)
    if missing:
        print(f"check_deps: {len(missing)} path(s) named in docs/ARCHITECTURE.md do not exist")
    if broken:
        print(f"check_deps: {len(broken)} include(s) break the rules in docs/ARCHITECTURE.md")
    if missing or broken:
        return 1
    print(f"check_deps: {len(files)} files, every include keeps the rules")
    print(f"check_deps: docs/ARCHITECTURE.md names {named} paths, each exists")
    return 0


if __name__ == "__main__":
    sys.exit(main())
