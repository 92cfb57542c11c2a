#!/usr/bin/env python3
"""Merge helper for the lead (issue 37), not part of the build: after merging a branch
that still cites moved docs (docs/robot.md, docs/DECISIONS.md D144, ...), rewrite those
paths to their place in the book, in every tracked file outside book/. Run from the
repository root: python3 merge-tools/fix_doc_paths.py (prints the files it changed)."""
import re, subprocess
files = subprocess.check_output(['git','ls-files'], text=True).split('\n')
files = [f for f in files if f and not f.startswith('book/') and f not in ('docs/DECISIONS.md','README.md','firmware/README.md') and not f.startswith('merge-tools/')
         and not f.endswith(('.png','.svg','.mcap','.lock','.bin','.elf'))]
DEP = {1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19,23,175}
def dec(m):
    n = int(m.group(2))
    return ('book/src/explanation/paper-departures.md' if n in DEP else 'book/src/explanation/decisions.md') + m.group(1) + 'D' + m.group(2)
subs = [
 (r'docs/DECISIONS\.md(`?,? ?)D(\d+)', dec),
 (r'DECISIONS D(\d+)', lambda m: ('book/src/explanation/paper-departures.md D' if int(m.group(1)) in DEP else 'book/src/explanation/decisions.md D')+m.group(1)),
 (r'D(\d+) in docs/DECISIONS\.md', lambda m: 'D%s in %s' % (m.group(1), 'book/src/explanation/paper-departures.md' if int(m.group(1)) in DEP else 'book/src/explanation/decisions.md')),
 (r'docs/robot\.md, "Derived values"', 'book/src/explanation/robot-file.md, "Derived values"'),
 (r'docs/robot\.md', 'book/src/how-to/robot-file.md'),
 (r'docs/scenario\.md', 'book/src/reference/scenario-file.md'),
 (r'docs/sweeps\.md', 'book/src/how-to/sweeps.md'),
 (r'docs/(tuning|identification|commissioning|bringup|python|foxglove|serve|ros2)\.md', r'book/src/how-to/\1.md'),
 (r'docs/foxglove-layout\.json', 'book/src/how-to/foxglove-layout.json'),
]
changed = []
for f in files:
    try: t = open(f, encoding='utf-8').read()
    except Exception: continue
    o = t
    for a, b in subs: t = re.sub(a, b, t)
    if t != o:
        open(f, 'w', encoding='utf-8').write(t); changed.append(f)
print('\n'.join(changed))
