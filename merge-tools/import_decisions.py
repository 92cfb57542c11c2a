#!/usr/bin/env python3
"""Merge helper for the lead (issue 37), not part of the build: move decision entries
that another branch appended to the old docs/DECISIONS.md into the new log.

usage: python3 merge-tools/import_decisions.py BRANCH|FILE [BRANCH|FILE...]

For each branch, reads `git show BRANCH:docs/DECISIONS.md`, takes every entry whose
number is not yet in book/src/explanation/decisions.md (entries start with
`**Dn. Title.**` or `## Dn: Title` / `## Dn. Title`), converts it to
`## Dn. Title {#dn}` + body, rewrites moved paths (docs/robot.md -> the book, ...),
and inserts it into the log in number order, with its line in the index.
Prints what it imported. Run it after merging the branch (keep book/'s version of
docs/DECISIONS.md: the stub).
"""

import os
import re
import subprocess
import sys

LOG = "book/src/explanation/decisions.md"
PATHS = [
    (r"docs/DECISIONS\.md", "book/src/explanation/decisions.md"),
    (r"docs/robot\.md", "book/src/how-to/robot-file.md"),
    (r"docs/scenario\.md", "book/src/reference/scenario-file.md"),
    (r"docs/(sweeps|tuning|identification|commissioning|bringup|python|foxglove|serve|ros2)\.md", r"book/src/how-to/\1.md"),
    (r"docs/foxglove-layout\.json", "book/src/how-to/foxglove-layout.json"),
    (r"firmware/README\.md", "book/src/how-to/flash-a-board.md"),
]


def entries(text):
    lines = text.split("\n")
    out, cur = {}, None
    fence = False
    for i, line in enumerate(lines):
        if line.startswith("```"):
            fence = not fence
        m1 = None if fence else re.match(r"^\*\*D(\d+)\. (.*)$", line)
        m2 = None if fence else re.match(r"^## D(\d+)[:.] (.*?)(?: \{#d\d+\})?$", line)
        if m1:
            n = int(m1.group(1))
            rest = m1.group(2)
            j = i
            buf = rest
            while "**" not in buf:
                j += 1
                buf += " " + lines[j]
            k = buf.index("**")
            title, body0 = buf[:k].strip().rstrip("."), buf[k + 2 :].strip()
            title = re.sub(r"\s+", " ", title)
            cur = out[n] = {"title": f"D{n}. {title}", "body": [body0] if body0 else [], "skip": j - i}
            continue
        if m2:
            n = int(m2.group(1))
            cur = out[n] = {"title": f"D{n}. {m2.group(2).strip()}", "body": [], "skip": 0}
            continue
        if not fence and (line.startswith("## ") or line.startswith("# ")):
            cur = None
            continue
        if cur is not None:
            if cur["skip"] > 0:
                cur["skip"] -= 1
                continue
            cur["body"].append(line)
    return out


def main():
    log = open(LOG, encoding="utf-8").read()
    have = {int(n) for n in re.findall(r"\{#d(\d+)\}", log)}
    new = {}
    for branch in sys.argv[1:]:
        if os.path.isfile(branch):  # a file in the old format (for a dry run)
            text = open(branch, encoding="utf-8").read()
        else:
            text = subprocess.check_output(["git", "show", f"{branch}:docs/DECISIONS.md"], text=True)
        for n, e in entries(text).items():
            if n not in have and n not in new:
                new[n] = e
    if not new:
        print("nothing to import")
        return 0
    for n in sorted(new):
        e = new[n]
        body = "\n".join(e["body"]).strip()
        for a, b in PATHS:
            body = re.sub(a, b, body)
        block = f"## {e['title']} {{#d{n}}}\n\n{body}\n"
        # insert before the first entry with a larger number, else at the end
        later = [m for m in re.finditer(r"^## D(\d+)\. .*\{#d\d+\}$", log, re.M) if int(m.group(1)) > n]
        if later:
            log = log[: later[0].start()] + block + "\n" + log[later[0].start() :]
        else:
            log = log.rstrip("\n") + "\n\n" + block
        index_line = f"- [{e['title']}](#d{n})\n"
        items = list(re.finditer(r"^- \[D(\d+)\. .*\]\(#d\d+\)\n", log, re.M))
        after = [m for m in items if int(m.group(1)) < n]
        pos = after[-1].end() if after else items[0].start()
        log = log[:pos] + index_line + log[pos:]
        print(f"imported D{n}: {e['title']}")
    open(LOG, "w", encoding="utf-8").write(log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
