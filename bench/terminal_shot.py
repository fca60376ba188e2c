"""Replays a terminal recording (script(1) output: text with ANSI escapes) through a small VT
emulator (110 columns; carriage return, line feed, cursor up/down/column, erase line, colours)
and writes the screen it leaves as HTML, for a picture of real terminal output
(docs/progress_precompute_*.png):

    script -q -c "stty cols 110 rows 40; ves precompute scene.toml -o x.h5" /dev/null > run.txt
    python3 bench/terminal_shot.py run.txt out.html "TITLE" [UPTO]
    chromium --headless --no-sandbox --hide-scrollbars --window-size=990,356 --screenshot=out.png file://$PWD/out.html

UPTO (bytes) cuts the recording there: a frame during the run (cut just before a redraw, an
ESC[2A, so the bars are whole).
"""
import html
import re
import sys

rec, out, title = sys.argv[1], sys.argv[2], sys.argv[3]
data = open(rec, "rb").read()
if len(sys.argv) > 4:
    data = data[: int(sys.argv[4])]
text = data.decode("utf-8", "replace")
COLS = 110
rows = [[]]  # each cell: (char, style)
r = c = 0
style = {"fg": None, "dim": False, "bold": False}
PALETTE = {30: "#2e3436", 31: "#ef5350", 32: "#8ae234", 33: "#e5c07b", 34: "#61afef", 35: "#c678dd",
           36: "#56b6c2", 37: "#d3d7cf", 90: "#7f8c8d", 91: "#ff6e6e", 92: "#a5e075", 93: "#f0d070",
           94: "#82aaff", 95: "#d7a0f0", 96: "#7fdbe0", 97: "#ffffff"}


def cell_style():
    return (style["fg"], style["dim"], style["bold"])


def ensure(row):
    while len(rows) <= row:
        rows.append([])


def put(ch):
    global r, c
    if c >= COLS:
        r, c = r + 1, 0
    ensure(r)
    line = rows[r]
    while len(line) < c:
        line.append((" ", (None, False, False)))
    if c < len(line):
        line[c] = (ch, cell_style())
    else:
        line.append((ch, cell_style()))
    c += 1


i = 0
esc = re.compile(r"\x1b\[([0-9;?]*)([A-Za-z])")
while i < len(text):
    ch = text[i]
    if ch == "\x1b":
        m = esc.match(text, i)
        if not m:
            i += 1
            continue
        args, cmd = m.group(1), m.group(2)
        n = int(args) if args.isdigit() else 1
        if cmd == "m":
            for a in (args or "0").split(";"):
                a = int(a) if a.isdigit() else 0
                if a == 0:
                    style = {"fg": None, "dim": False, "bold": False}
                elif a == 1:
                    style["bold"] = True
                elif a == 2:
                    style["dim"] = True
                elif a in (22,):
                    style["bold"] = style["dim"] = False
                elif a == 39:
                    style["fg"] = None
                elif a in PALETTE:
                    style["fg"] = a
        elif cmd == "A":
            r = max(0, r - n)
        elif cmd == "B":
            r += n
            ensure(r)
        elif cmd == "G":
            c = n - 1
        elif cmd == "K":
            ensure(r)
            if args in ("2",):
                rows[r] = []
            else:
                rows[r] = rows[r][:c]
        i = m.end()
        continue
    if ch == "\r":
        c = 0
    elif ch == "\n":
        r, c = r + 1, 0
        ensure(r)
    elif ch >= " ":
        put(ch)
    i += 1

# Trailing empty rows are not shown.
while rows and not "".join(x[0] for x in rows[-1]).strip():
    rows.pop()
body = []
for line in rows:
    spans, cur, buf = [], None, ""
    for ch, st in line + [("", "end")]:
        if st != cur:
            if buf:
                fg, dim, bold = cur
                css = []
                if fg:
                    css.append("color:%s" % PALETTE[fg])
                if dim:
                    css.append("opacity:0.6")
                if bold:
                    css.append("font-weight:bold")
                spans.append('<span style="%s">%s</span>' % (";".join(css), html.escape(buf)) if css else html.escape(buf))
            cur, buf = st, ""
        buf += ch
    body.append("".join(spans))
page = """<!doctype html><meta charset="utf-8"><style>
body{margin:0;background:#3b3f45;font-family:'DejaVu Sans Mono',monospace}
.win{margin:16px;border-radius:8px;overflow:hidden;box-shadow:0 4px 16px #0008;display:inline-block}
.bar{background:#2b2e33;color:#bbb;font:13px 'DejaVu Sans',sans-serif;padding:7px 12px}
pre{margin:0;padding:12px 14px;background:#1e2127;color:#d3d7cf;font-size:14px;line-height:1.3;width:%dch;white-space:pre}
</style><div class="win"><div class="bar">%s</div><pre>%s</pre></div>""" % (COLS, html.escape(title), "\n".join(body))
open(out, "w").write(page)
print(len(rows), "rows")
