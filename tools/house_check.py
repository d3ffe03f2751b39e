#!/usr/bin/env python3
"""Issue 40's house figures for a crate folder: product lines (without `#[cfg(test)]` modules)
and functions longer than a limit. Usage: tools/house_check.py crates/mimic/src [--max-fn 100]
Exit 1 when a function is longer than --max-fn or the product lines pass --max-lines."""
import argparse, pathlib, re, sys

def strip_tests(lines):
    out, skip, depth = [], False, 0
    i = 0
    while i < len(lines):
        l = lines[i]
        if not skip and l.strip() == "#[cfg(test)]" and i + 1 < len(lines) and re.match(r"\s*(pub\s+)?mod\s+\w+\s*(\{|;)", lines[i + 1]):
            if lines[i + 1].rstrip().endswith(";"):
                i += 2
                continue
            skip, depth = True, 0
        if skip:
            depth += l.count("{") - l.count("}")
            if depth <= 0 and "}" in l:
                skip = False
            i += 1
            continue
        out.append(l)
        i += 1
    return out

def functions(lines):
    """(name, start line, length) of each fn, by brace matching from its signature."""
    res = []
    for i, l in enumerate(lines):
        m = re.match(r"\s*(pub(\([^)]*\))?\s+)?(async\s+)?(const\s+)?(unsafe\s+)?fn\s+(\w+)", l)
        if not m:
            continue
        depth, started = 0, False
        for j in range(i, len(lines)):
            s = re.sub(r'"([^"\\]|\\.)*"', '""', lines[j])
            s = re.sub(r"'([^'\\]|\\.)'", "''", s)
            s = s.split("//")[0]
            if not started and ";" in s and "{" not in s:
                break
            depth += s.count("{") - s.count("}")
            if "{" in s:
                started = True
            if started and depth <= 0:
                res.append((m.group(6), i + 1, j - i + 1))
                break
    return res

ap = argparse.ArgumentParser()
ap.add_argument("root")
ap.add_argument("--max-fn", type=int, default=100)
ap.add_argument("--max-lines", type=int, default=0)
a = ap.parse_args()
total, bad = 0, []
for p in sorted(pathlib.Path(a.root).rglob("*.rs")):
    lines = strip_tests(p.read_text().splitlines())
    total += len(lines)
    for name, start, n in functions(lines):
        if n > a.max_fn:
            bad.append(f"{p}:{start}: fn {name} is {n} lines")
print(f"{a.root}: {total} lines of product code (test modules left out)")
for b in bad:
    print(b)
sys.exit(1 if bad or (a.max_lines and total > a.max_lines) else 0)
