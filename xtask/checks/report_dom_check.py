#!/usr/bin/env python3
"""The demo report as a person sees it: reads the DOM headless Chromium built from report/index.html
and the screenshot it took; checks every required section is present and non-empty, every inline
SVG draws marks, every table has filled body rows, no script or external resource, and the
screenshot is not blank. Usage: report_dom_check.py DOM.html SCREENSHOT.png"""
import sys
from html.parser import HTMLParser

REQUIRED = ["run", "summary", "data", "classifiers", "confusion", "early", "release", "can", "estimator",
            "audit", "firmware"]
MIN_SVGS = 12     # accuracy vs time, 5 release curves, 3 estimator scatters, 3 audit plots
MIN_TABLES = 14
MARKS = {"path", "polyline", "polygon", "circle", "line", "rect", "text"}


class Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.stack = []            # open elements
        self.sections = {}         # id -> count of content elements / text
        self.section = None
        self.svgs = []             # per svg: drawn marks
        self.tables = []           # per table: [body rows, filled cells]
        self.in_td = False
        self.bad = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ("script", "iframe", "img", "link", "object", "embed"):
            self.bad.append(tag)
        for k in ("src", "href"):
            v = a.get(k) or ""
            if v.startswith(("http:", "https:", "//")):
                self.bad.append(f"{tag} {k}={v}")
        if tag == "section":
            self.section = a.get("id")
            self.sections[self.section] = 0
        elif self.section is not None and tag not in ("h2",):
            self.sections[self.section] += 1
        if tag == "svg" and not any(t == "svg" for t in self.stack):
            self.svgs.append(0)
        elif tag in MARKS and any(t == "svg" for t in self.stack) and self.svgs:
            self.svgs[-1] += 1
        if tag == "table":
            self.tables.append([0, 0])
        elif tag == "tr" and "tbody" in self.stack and self.tables:
            self.tables[-1][0] += 1
        elif tag == "td":
            self.in_td = True
        if tag not in ("meta", "br", "hr", "input") and not (tag in MARKS and tag != "text"):
            self.stack.append(tag)

    def handle_startendtag(self, tag, attrs):
        self.handle_starttag(tag, attrs)

    def handle_endtag(self, tag):
        if tag == "td":
            self.in_td = False
        if tag == "section":
            self.section = None
        if tag in self.stack:
            while self.stack and self.stack.pop() != tag:
                pass

    def handle_data(self, data):
        if self.in_td and data.strip() and self.tables:
            self.tables[-1][1] += 1


dom_path, shot_path = sys.argv[1], sys.argv[2]
p = Page()
p.feed(open(dom_path, encoding="utf-8").read())
errors = []
if p.bad:
    errors.append(f"script or external resource in the page: {p.bad[:5]}")
for sid in REQUIRED:
    if sid not in p.sections:
        errors.append(f"section #{sid} missing")
    elif p.sections[sid] == 0:
        errors.append(f"section #{sid} is empty")
for i, marks in enumerate(p.svgs):
    if marks < 3:
        errors.append(f"plot {i + 1} draws nothing ({marks} marks)")
for i, (rows, cells) in enumerate(p.tables):
    if rows == 0 or cells == 0:
        errors.append(f"table {i + 1} has no filled rows ({rows} rows, {cells} filled cells)")
if len(p.svgs) < MIN_SVGS:
    errors.append(f"{len(p.svgs)} plots, expected at least {MIN_SVGS}")
if len(p.tables) < MIN_TABLES:
    errors.append(f"{len(p.tables)} tables, expected at least {MIN_TABLES}")
shot = open(shot_path, "rb").read()
if not shot.startswith(b"\x89PNG") or len(shot) < 40000:
    errors.append(f"screenshot {shot_path} missing or blank ({len(shot)} bytes)")
print(f"sections {len(p.sections)}: {', '.join(p.sections)}")
print(f"plots {len(p.svgs)} (marks per plot: min {min(p.svgs, default=0)}), tables {len(p.tables)} "
      f"({sum(r for r, _ in p.tables)} body rows), screenshot {len(shot)} bytes")
if errors:
    print("FAILED:\n  " + "\n  ".join(errors))
    sys.exit(1)
