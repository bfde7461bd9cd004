#!/usr/bin/env python3
"""Checks the relative links of the docs book and the README: every linked file exists and every
#anchor names a heading of its target (mdBook's heading ids). mdBook itself does not check them.
Usage: python3 docs/check-links.py   (from anywhere; exit 1 and one line per broken link)"""
import glob
import os
import re
import sys

root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))


def slug(heading):
    heading = heading.replace('`', '').strip().lower()
    return ''.join(c if c.isalnum() or c in '-_' else '-' if c == ' ' else '' for c in heading)


def anchors(path):
    ids, seen, code = set(), {}, False
    for line in open(path, encoding='utf-8'):
        if line.startswith('```'):
            code = not code
        if not code and re.match(r'^#{1,6} ', line):
            s = slug(line.lstrip('#'))
            if s in seen:
                seen[s] += 1
                s = f'{s}-{seen[s]}'
            else:
                seen[s] = 0
            ids.add(s)
    return ids


files = glob.glob(os.path.join(root, 'docs/src/**/*.md'), recursive=True) + [os.path.join(root, 'README.md')]
bad = 0
for f in files:
    text = re.sub(r'```.*?```', '', open(f, encoding='utf-8').read(), flags=re.S)
    for m in re.finditer(r'\]\(([^)\s]+)\)', text):
        link = m.group(1)
        if re.match(r'^[a-z]+:', link):
            continue
        path, _, anchor = link.partition('#')
        target = os.path.normpath(os.path.join(os.path.dirname(f), path)) if path else f
        where = os.path.relpath(f, root)
        if not os.path.exists(target):
            print(f'{where}: link to a missing file: {link}')
            bad += 1
        elif anchor and target.endswith('.md') and anchor not in anchors(target):
            print(f'{where}: link to a missing heading: {link}')
            bad += 1
sys.exit(1 if bad else 0)
