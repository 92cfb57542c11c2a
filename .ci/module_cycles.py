#!/usr/bin/env python3
"""Import-cycle check between the modules of each crate (issue 17).

A module may use the modules below it, never one that uses it back. For
every crate (a folder with Cargo.toml and src/), this script builds the
module tree from the files (src/lib.rs or src/main.rs is the root,
src/a.rs or src/a/mod.rs is `a`, src/a/b.rs is `a::b`), collects every path
a module names (`use crate::...`, `crate::x::y` in code, `super::...`,
`self::...` in `use`), and turns each into an edge between the two sibling
modules under the paths' lowest common ancestor (a module naming its own
parent or child is not an edge: that is what nesting means). A cycle among
siblings fails the check. Comments and string literals are ignored, so doc
links do not count. `#[path]`-included files are checked in the crate that
owns them.

Usage: python3 .ci/module_cycles.py [CRATE_DIR ...]   (default: every crate
in the repository). Exit 1 with the cycles listed, 0 when there is none.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SKIP_DIRS = {"target", ".git", "node_modules", "out"}


def strip_comments_and_strings(src):
    """Source with comments, string and char literals blanked out."""
    out = []
    i, n = 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            i = n if j < 0 else j
            continue
        if src.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if src.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif src.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
            continue
        m = re.match(r'b?r(#*)"', src[i:i + 40])
        if m and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")):
            end = '"' + m.group(1)
            j = src.find(end, i + len(m.group(0)))
            i = n if j < 0 else j + len(end)
            out.append('""')
            continue
        if c == '"':
            i += 1
            while i < n and src[i] != '"':
                i += 2 if src[i] == "\\" else 1
            i += 1
            out.append('""')
            continue
        if c == "'":
            # char literal ('a', '\n', '\u{..}') vs lifetime ('a)
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", src[i:i + 12])
            if m:
                i += len(m.group(0))
                out.append("' '")
                continue
        out.append(c)
        i += 1
    return "".join(out)


def module_files(src_dir):
    """Map module path tuple -> file for every .rs file under src/."""
    mods = {}
    for dirpath, dirnames, filenames in os.walk(src_dir):
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and d != "bin"]
        for f in filenames:
            if not f.endswith(".rs"):
                continue
            rel = os.path.relpath(os.path.join(dirpath, f), src_dir)
            parts = rel[:-3].split(os.sep)
            if parts == ["lib"] or parts == ["main"]:
                parts = []
            elif parts[-1] == "mod":
                parts = parts[:-1]
            mods[tuple(parts)] = os.path.join(dirpath, f)
    return mods


def parse_use_tree(text, pos):
    """Parse a `use` tree starting at pos; return (list of paths, end)."""
    paths = []

    def tree(i, prefix):
        i = skip_ws(text, i)
        if text.startswith("{", i):
            i += 1
            while True:
                i = skip_ws(text, i)
                if text.startswith("}", i):
                    return i + 1
                i = tree(i, prefix)
                i = skip_ws(text, i)
                if text.startswith(",", i):
                    i += 1
        m = re.match(r"(\w+|\*)", text[i:])
        if not m:
            paths.append(prefix)
            return i
        name = m.group(1)
        i += len(name)
        i = skip_ws(text, i)
        if text.startswith("::", i):
            return tree(i + 2, prefix + [name])
        if name not in ("*", "self"):
            paths.append(prefix + [name])
        else:
            paths.append(prefix)
        m = re.match(r"\s*as\s+\w+", text[i:])
        if m:
            i += len(m.group(0))
        return i

    end = tree(pos, [])
    return paths, end


def skip_ws(text, i):
    while i < len(text) and text[i].isspace():
        i += 1
    return i


def references(code, here):
    """Absolute module paths (lists) named by the code of module `here`."""
    refs = []
    for m in re.finditer(r"\buse\s+", code):
        paths, _ = parse_use_tree(code, m.end())
        for p in paths:
            refs.append(resolve(p, here))
    for m in re.finditer(r"(?<![\w:])((?:crate|super|self)(?:\s*::\s*\w+)+)", code):
        p = [s.strip() for s in m.group(1).split("::")]
        refs.append(resolve(p, here))
    return [r for r in refs if r is not None]


def resolve(path, here):
    if not path:
        return None
    if path[0] == "crate":
        return path[1:]
    if path[0] in ("super", "self"):
        base = list(here)
        i = 0
        while i < len(path) and path[i] in ("super", "self"):
            if path[i] == "super":
                if not base:
                    return None
                base.pop()
            i += 1
        return base + path[i:]
    return None  # an external crate or a local name


def longest_module(path, mods):
    for k in range(len(path), -1, -1):
        if tuple(path[:k]) in mods:
            return tuple(path[:k])
    return ()


TEST_MOD = re.compile(r"#\[cfg\(test\)\]\s*(?:#\[[^\]]*\]\s*)*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*([;{])")


def strip_test_blocks(code):
    """Code without inline `#[cfg(test)] mod x { ... }` blocks; the names
    of `#[cfg(test)] mod x;` children (test code may use anything)."""
    out, test_children, i = [], set(), 0
    for m in TEST_MOD.finditer(code):
        if m.start() < i:
            continue
        if m.group(2) == ";":
            test_children.add(m.group(1))
            continue
        out.append(code[i:m.start()])
        depth, j = 1, m.end()
        while j < len(code) and depth:
            depth += {"{": 1, "}": -1}.get(code[j], 0)
            j += 1
        i = j
    out.append(code[i:])
    return "".join(out), test_children


def check_crate(crate_dir):
    src = os.path.join(crate_dir, "src")
    mods = module_files(src)
    codes, test_mods = {}, set()
    for here, f in mods.items():
        with open(f, encoding="utf-8") as fh:
            code, children = strip_test_blocks(strip_comments_and_strings(fh.read()))
        codes[here] = code
        test_mods.update(here + (c,) for c in children)
    edges = {}
    for here, code in codes.items():
        if any(here[:k] in test_mods for k in range(1, len(here) + 1)):
            continue  # test-only module
        for ref in references(code, list(here)):
            target = longest_module(ref, mods)
            k = 0
            while k < min(len(here), len(target)) and here[k] == target[k]:
                k += 1
            if k == len(here) or k == len(target):
                continue  # own ancestor or descendant
            a, b = here[: k + 1], target[: k + 1]
            edges.setdefault(a, set()).add(b)
    return find_cycles(edges)


def find_cycles(edges):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index:
            visit(v)
    # describe each component by the edges inside it
    described = []
    for comp in out:
        s = set(comp)
        inside = sorted(
            ("::".join(a), "::".join(b)) for a in comp for b in edges.get(a, ()) if b in s
        )
        described.append(inside)
    return described


def crates(root):
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and not d.startswith(".")]
        if "Cargo.toml" in filenames and os.path.isdir(os.path.join(dirpath, "src")):
            found.append(dirpath)
    return sorted(found)


def self_test():
    """Negative and positive controls on crates made in a temporary folder."""
    import tempfile

    def make(files):
        d = tempfile.mkdtemp()
        os.makedirs(os.path.join(d, "src", "c"))
        open(os.path.join(d, "Cargo.toml"), "w").close()
        for name, text in files.items():
            with open(os.path.join(d, "src", name), "w") as fh:
                fh.write(text)
        return d

    cyclic = make({
        "lib.rs": "mod a; mod b; mod c;",
        "a.rs": "use crate::b::{x, y as z};",
        "b.rs": "pub fn x() { crate::c::d::f(); }",
        "c/mod.rs": "pub mod d;",
        "c/d.rs": "use super::super::a::g;",
    })
    assert check_crate(cyclic) == [[("a", "b"), ("b", "c"), ("c", "a")]], check_crate(cyclic)
    clean = make({
        "lib.rs": "mod a; mod b; mod c; #[cfg(test)] mod t;",
        "a.rs": "use crate::b::x; // crate::c::y\n/// [`crate::c`]\nconst S: &str = \"crate::c::z\";",
        "b.rs": "use super::c::q; #[cfg(test)] mod tests { use crate::a::f; }",
        "c/mod.rs": "pub mod d; use self::d::k;",
        "c/d.rs": "use super::k2;",
        "t.rs": "use crate::a::f; use crate::c::k;",
    })
    assert check_crate(clean) == [], check_crate(clean)
    print("self-test passed: a cycle through a nested module is found; comments, strings, "
          "parent/child paths and test code are not edges")


def main():
    if sys.argv[1:] == ["--self-test"]:
        self_test()
        return 0
    dirs = sys.argv[1:] or crates(ROOT)
    bad = 0
    for d in dirs:
        cycles = check_crate(d)
        name = os.path.relpath(d, ROOT)
        if cycles:
            bad += len(cycles)
            for comp in cycles:
                print(f"FAIL {name}: import cycle: " + ", ".join(f"{a} -> {b}" for a, b in comp))
        else:
            print(f"ok   {name}")
    if bad:
        print(f"{bad} import cycle(s)")
        return 1
    print("no import cycle in any crate")
    return 0


if __name__ == "__main__":
    sys.exit(main())
