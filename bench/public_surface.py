#!/usr/bin/env python3
"""Count dbbcal-core's public surface and list what no other part of the workspace names.

Usage: python3 bench/public_surface.py [--list]   (from the repository root)

Counted in crates/core/src (unit-test files `tests.rs` and `*_tests.rs` left out):
- public items: declarations with exactly `pub` (not `pub(crate)`/`pub(super)`) of a fn (free
  or method), struct, enum, const, static, type or trait; `pub mod` and `pub use` are counted
  apart (modules and re-exports are paths, not items);
- public fields: `pub name:` lines inside a struct's braces, and `pub` tuple-struct fields.

"Named outside core" means the item's name occurs as a word in any `.rs` file of the other
crates (`crates/*` but core, their examples and tests included), of the application (`src/`),
of `tests/` or `bench/`, or inside a code block of one of core's own doc comments (doctests
compile as an outside crate). Occurrences in comments count too: the check is deliberately
conservative (a name that also means something else elsewhere keeps its item public).
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORE = os.path.join(ROOT, "crates", "core", "src")
ITEM = re.compile(
    r"^\s*pub (?:const fn|unsafe fn|async fn|fn|struct|enum|const|static|type|trait)\s+([A-Za-z_][A-Za-z0-9_]*)"
)
FIELD = re.compile(r"^\s+pub ([a-z_][a-z0-9_]*)\s*:")
TUPLE_FIELDS = re.compile(r"^\s*pub struct \w+(?:<[^>]*>)?\((.*)\)\s*;")


def rust_files(top):
    for d, _, files in os.walk(top):
        for f in sorted(files):
            if f.endswith(".rs"):
                yield os.path.join(d, f)


def is_test_file(path):
    name = os.path.basename(path)
    return name == "tests.rs" or name.endswith("_tests.rs")


def core_declarations():
    items, fields, mods, uses = [], [], 0, 0
    for path in rust_files(CORE):
        if is_test_file(path):
            continue
        in_struct = False
        depth = 0
        for n, line in enumerate(open(path, encoding="utf-8"), 1):
            code = line.split("//")[0]
            if re.match(r"^\s*pub mod ", code):
                mods += 1
            if re.match(r"^\s*pub use ", code):
                uses += 1
            m = ITEM.match(code)
            if m:
                items.append((m.group(1), path, n))
                t = TUPLE_FIELDS.match(code)
                if t:
                    fields.extend(("(tuple)", path, n) for f in t.group(1).split(",") if f.strip().startswith("pub "))
            if re.match(r"^\s*(?:pub(?:\([\w:]+\))? )?struct \w+[^;(]*\{\s*$", code):
                in_struct, depth = True, 0
            if in_struct:
                depth += code.count("{") - code.count("}")
                f = FIELD.match(code)
                if f and depth == 1:
                    fields.append((f.group(1), path, n))
                if depth <= 0 and "}" in code:
                    in_struct = False
    return items, fields, mods, uses


def outside_words():
    words = set()
    tops = [os.path.join(ROOT, "src"), os.path.join(ROOT, "tests"), os.path.join(ROOT, "bench")]
    crates = os.path.join(ROOT, "crates")
    tops += [os.path.join(crates, c) for c in sorted(os.listdir(crates)) if c != "core"]
    for top in tops:
        for path in rust_files(top):
            words.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", open(path, encoding="utf-8").read()))
    # Doctests of core are compiled as an outside crate.
    for path in rust_files(CORE):
        fence = False
        for line in open(path, encoding="utf-8"):
            s = line.strip()
            if s.startswith("///") or s.startswith("//!"):
                body = s[3:].strip()
                if body.startswith("```"):
                    fence = not fence and body in ("```", "```rust", "```no_run")
                    continue
                if fence:
                    words.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", body))
            else:
                fence = False
    return words


def main():
    items, fields, mods, uses = core_declarations()
    words = outside_words()
    unnamed_items = [i for i in items if i[0] not in words]
    unnamed_fields = [f for f in fields if f[0] != "(tuple)" and f[0] not in words]
    print(f"public items:  {len(items)} (not named outside core: {len(unnamed_items)})")
    print(f"public fields: {len(fields)} (not named outside core: {len(unnamed_fields)})")
    print(f"pub mod: {mods}, pub use: {uses}")
    if "--list" in sys.argv:
        for kind, rows in (("item", unnamed_items), ("field", unnamed_fields)):
            for name, path, n in rows:
                print(f"{kind}\t{os.path.relpath(path, ROOT)}:{n}\t{name}")


if __name__ == "__main__":
    main()
