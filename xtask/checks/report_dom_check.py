#!/usr/bin/env python3
"""The demo report as a person sees it, from what headless Chromium rendered (standard library only).

    report_dom_check.py demo DOM.html SCREENSHOT.png SCROLL.png REPORT_DIR
    report_dom_check.py locomotive DOM.html SCREENSHOT.png SCROLL.png REPORT_DIR
    report_dom_check.py overflow SCROLL.png
    report_dom_check.py legends FILE.html|FILE.svg

`demo` checks the demo's index page (the fleet table first, then the rest of the report), `locomotive`
one locomotive page. Both check: every required section present and non-empty, every inline SVG
drawing marks, every table with filled body rows, no script or external resource, the screenshot
not blank, plot text of at least 11 px, no legend (nor any other text or box) drawn inside a plot's
data rectangle, and no horizontal overflow at 1280 px. The fleet table must
come first and link every locomotive to a page that exists in REPORT_DIR. `overflow` only runs the overflow check (exit status 1 when the page overflows), `legends` only the
legend check on a page or an SVG file (exit status 1 when something covers a plot's data).

Legends: a plot drawn by plotters marks its data rectangle with its mesh, faint (opacity < 0.5)
grid lines across it: the vertical ones span the rectangle's height, the horizontal ones its
width (one rectangle per panel). Axis text and the legend row above the plot lie outside it; a
text or a box whose anchor lies inside it, like plotters' own series-label box, covers data.
Plots without such a mesh (the fleet pages' hand-drawn SVG) are not looked at.

Overflow: SCROLL.png is a 1280 px wide screenshot taken with scrollbars. When the page is wider
than the window, Chromium draws a horizontal scrollbar along the bottom of the viewport (a band of
uniform light grey rows across the width, with a darker thumb), however long the page is; the page
itself never paints such a band (its background is not a neutral grey)."""
import os
import re
import struct
import sys
import zlib
from html.parser import HTMLParser

DEMO_SECTIONS = ["fleet", "run", "summary", "data", "classifiers", "confusion", "early", "release", "can",
                 "estimator", "audit", "firmware"]
LOCO_SECTIONS = ["summary", "curves", "trends", "can"]
# accuracy vs time, reliability, 5 release curves, 3 estimator scatters, 2 real-record plots, 3 audit
# plots, one sparkline per locomotive (5)
MIN_SVGS = {"demo": 20, "locomotive": 4}
MIN_TABLES = {"demo": 15, "locomotive": 2}
MIN_FLEET_ROWS = 5
MIN_PLOT_TEXT_PX = 11.0
MARKS = {"path", "polyline", "polygon", "circle", "line", "rect", "text"}
# Inset of a data rectangle, px: a text or box anchored this close to its edge is on the frame.
DATA_INSET_PX = 3.0


class Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.stack = []            # open elements
        self.sections = {}         # id -> count of content elements / text
        self.section = None
        self.svgs = []             # per svg: [drawn marks, section, smallest font size]
        self.shapes = []           # per svg: [(tag, attributes, text)] of its lines, texts and boxes
        self.tables = []           # per table: [body rows, filled cells, section]
        self.links = []            # (section, href)
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
        if tag == "a" and a.get("href"):
            self.links.append((self.section, a["href"]))
        if tag == "section":
            self.section = a.get("id")
            self.sections[self.section] = 0
        elif self.section is not None and tag not in ("h2",):
            self.sections[self.section] += 1
        in_svg = any(t == "svg" for t in self.stack)
        if tag == "svg" and not in_svg:
            self.svgs.append([0, self.section, float("inf")])
            self.shapes.append([])
        elif tag in MARKS and in_svg and self.svgs:
            self.svgs[-1][0] += 1
            if tag in ("line", "text", "rect"):
                self.shapes[-1].append([tag, a, ""])
        if (tag == "svg" or in_svg) and self.svgs and a.get("font-size"):
            m = re.match(r"\s*([0-9.]+)", a["font-size"])
            if m:
                self.svgs[-1][2] = min(self.svgs[-1][2], float(m.group(1)))
        if tag == "table":
            self.tables.append([0, 0, self.section])
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
        if self.stack[-1:] == ["text"] and self.shapes and self.shapes[-1] and self.shapes[-1][-1][0] == "text":
            self.shapes[-1][-1][2] += data


def _num(a, key):
    try:
        return float(re.match(r"\s*(-?[0-9.]+)", a.get(key, "")).group(1))
    except (AttributeError, ValueError):
        return None


def data_rectangles(shapes):
    """The data rectangles (x0, y0, x1, y1) of one plotters plot, one per panel, from its mesh."""
    vertical, horizontal = {}, []
    for tag, a, _ in shapes:
        opacity = _num(a, "opacity")
        if tag != "line" or opacity is None or opacity >= 0.5:
            continue
        x1, y1, x2, y2 = (_num(a, k) for k in ("x1", "y1", "x2", "y2"))
        if None in (x1, y1, x2, y2):
            continue
        if x1 == x2 and y1 != y2:
            vertical.setdefault((min(y1, y2), max(y1, y2)), []).append(x1)
        elif y1 == y2 and x1 != x2:
            horizontal.append((y1, min(x1, x2), max(x1, x2)))
    rects = []
    for (y0, y1), xs in vertical.items():
        spans = [(a, b) for y, a, b in horizontal if y0 <= y <= y1]
        x0 = min([a for a, _ in spans] + xs)
        x1 = max([b for _, b in spans] + xs)
        rects.append((x0, y0, x1, y1))
    return rects


def covering_data(shapes):
    """Texts and boxes of one plot anchored inside one of its data rectangles."""
    found = []
    for x0, y0, x1, y1 in data_rectangles(shapes):
        inside = lambda x, y: x0 + DATA_INSET_PX < x < x1 - DATA_INSET_PX and y0 + DATA_INSET_PX < y < y1 - DATA_INSET_PX
        for tag, a, text in shapes:
            x, y = _num(a, "x"), _num(a, "y")
            if tag in ("text", "rect") and x is not None and y is not None and inside(x, y):
                what = f"text '{text.strip()[:30]}'" if tag == "text" else "box"
                found.append(f"{what} at ({x:g}, {y:g}) inside the data rectangle "
                             f"({x0:g}, {y0:g})-({x1:g}, {y1:g})")
    return found


def read_png(path):
    """Width, height and rows of RGB(A) bytes of a non-interlaced 8-bit PNG."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, w = 8, b"", 0
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                raise ValueError(f"{path}: unsupported PNG (depth {depth}, colour type {ctype})")
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    bpp = 3 if ctype == 2 else 4
    raw = zlib.decompress(idat)
    stride = w * bpp
    rows, prev, i = [], bytearray(stride), 0
    for _ in range(h):
        f = raw[i]
        line = bytearray(raw[i + 1:i + 1 + stride])
        i += 1 + stride
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 1:
                line[x] = (line[x] + a) & 255
            elif f == 2:
                line[x] = (line[x] + b) & 255
            elif f == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return w, h, bpp, rows


def horizontal_scrollbar(path):
    """Whether the screenshot shows a horizontal scrollbar along its bottom edge, and why."""
    w, h, bpp, rows = read_png(path)
    right = w - 16                       # the vertical scrollbar's column
    px = lambda row, x: tuple(row[x * bpp:x * bpp + 3])
    grey = lambda c, lo, hi: max(c) - min(c) <= 2 and lo <= c[0] <= hi
    # The track: the bottom rows uniform across the width, a light neutral grey.
    uniform = 0
    for y in range(h - 1, max(h - 20, 0), -1):
        first = px(rows[y], 0)
        if grey(first, 235, 254) and all(px(rows[y], x) == first for x in range(0, right)):
            uniform += 1
        else:
            break
    # The thumb: a run of at least 20 px of a darker neutral grey in the bottom 17 rows.
    thumb = 0
    for y in range(h - 17, h):
        run = 0
        for x in range(right):
            c = px(rows[y], x)
            run = run + 1 if grey(c, 60, 215) else 0
            thumb = max(thumb, run)
    return uniform >= 2 and thumb >= 20, f"{uniform} track rows, thumb run {thumb} px"


def blank(path):
    shot = open(path, "rb").read()
    return not shot.startswith(b"\x89PNG") or len(shot) < 40000, len(shot)


def main():
    kind = sys.argv[1]
    if kind == "overflow":
        over, why = horizontal_scrollbar(sys.argv[2])
        print(f"overflow: {'yes' if over else 'no'} ({why})")
        sys.exit(1 if over else 0)
    if kind == "legends":
        p = Page()
        p.feed(open(sys.argv[2], encoding="utf-8").read())
        found = [f"plot {i + 1}: {f}" for i, shapes in enumerate(p.shapes) for f in covering_data(shapes)]
        panels = sum(len(data_rectangles(shapes)) for shapes in p.shapes)
        print(f"legends: {len(p.shapes)} plots, {panels} data rectangles, {len(found)} texts or boxes over data")
        if found:
            print("FAILED:\n  " + "\n  ".join(found[:10]))
        sys.exit(1 if found else 0)
    dom_path, shot_path, scroll_path, report_dir = sys.argv[2:6]
    p = Page()
    p.feed(open(dom_path, encoding="utf-8").read())
    errors = []
    required = DEMO_SECTIONS if kind == "demo" else LOCO_SECTIONS
    if p.bad:
        errors.append(f"script or external resource in the page: {p.bad[:5]}")
    for sid in required:
        if sid not in p.sections:
            errors.append(f"section #{sid} missing")
        elif p.sections[sid] == 0:
            errors.append(f"section #{sid} is empty")
    if kind == "demo" and list(p.sections)[:1] != ["fleet"]:
        errors.append(f"the fleet table is not the first section ({list(p.sections)[:3]})")
    for i, (marks, section, font) in enumerate(p.svgs):
        if marks < 3:
            errors.append(f"plot {i + 1} draws nothing ({marks} marks)")
        if font < MIN_PLOT_TEXT_PX:
            errors.append(f"plot {i + 1} (section {section}) has {font} px text, below {MIN_PLOT_TEXT_PX}")
    for i, shapes in enumerate(p.shapes):
        for f in covering_data(shapes)[:3]:
            errors.append(f"plot {i + 1} (section {p.svgs[i][1]}): {f} (a legend over the data?)")
    panels = sum(len(data_rectangles(shapes)) for shapes in p.shapes)
    for i, (rows, cells, _) in enumerate(p.tables):
        if rows == 0 or cells == 0:
            errors.append(f"table {i + 1} has no filled rows ({rows} rows, {cells} filled cells)")
    if len(p.svgs) < MIN_SVGS[kind]:
        errors.append(f"{len(p.svgs)} plots, expected at least {MIN_SVGS[kind]}")
    if len(p.tables) < MIN_TABLES[kind]:
        errors.append(f"{len(p.tables)} tables, expected at least {MIN_TABLES[kind]}")
    local = [href for _, href in p.links if not href.startswith("#")]
    for href in local:
        if not os.path.isfile(os.path.join(report_dir, href)):
            errors.append(f"link to {href}, which is not in {report_dir}")
    if kind == "demo":
        fleet_rows = sum(r for r, _, s in p.tables if s == "fleet")
        fleet_links = [h for s, h in p.links if s == "fleet" and h.endswith(".html")]
        if fleet_rows < MIN_FLEET_ROWS:
            errors.append(f"the fleet table has {fleet_rows} locomotives, expected at least {MIN_FLEET_ROWS}")
        if len(fleet_links) < fleet_rows:
            errors.append(f"{fleet_rows} locomotives but {len(fleet_links)} links to their pages")
    else:
        if "index.html" not in local:
            errors.append("no link back to the fleet (index.html)")
    is_blank, size = blank(shot_path)
    if is_blank:
        errors.append(f"screenshot {shot_path} missing or blank ({size} bytes)")
    over, why = horizontal_scrollbar(scroll_path)
    if over:
        errors.append(f"the page is wider than 1280 px: a horizontal scrollbar in {scroll_path} ({why})")
    print(f"{kind} page {dom_path}: sections {len(p.sections)}: {', '.join(str(s) for s in p.sections)}")
    print(f"plots {len(p.svgs)} (marks per plot: min {min((m for m, _, _ in p.svgs), default=0)}), tables "
          f"{len(p.tables)} ({sum(r for r, _, _ in p.tables)} body rows), links {len(local)}, screenshot {size} "
          f"bytes, plot data rectangles checked for legends {panels}, overflow at 1280 px: {'yes' if over else 'no'} ({why})")
    if errors:
        print("FAILED:\n  " + "\n  ".join(errors))
        sys.exit(1)


main()
