#!/usr/bin/env python3
"""Lists the functions of N or more lines (default 100) in src/ and include/.

A function's length is ctags' end line - start line + 1 (Universal Ctags,
--fields=+n+e), the count issue reviews quote. Run from the repository root:
    python3 scripts/long_functions.py [min_lines]
"""
import json
import subprocess
import sys

min_lines = int(sys.argv[1]) if len(sys.argv) > 1 else 100
out = subprocess.run(
    ["ctags", "--output-format=json", "--fields=+n+e", "--languages=C++",
     "--kinds-C++=f", "-R", "-f", "-", "src", "include"],
    check=True, capture_output=True, text=True).stdout
rows = []
for line in out.splitlines():
    tag = json.loads(line)
    if tag.get("kind") != "function" or "end" not in tag:
        continue
    n = tag["end"] - tag["line"] + 1
    if n >= min_lines:
        scope = tag.get("scope", "")
        # Anonymous namespaces are named __anonXXXX by ctags: drop them.
        scope = "::".join(p for p in scope.split("::") if not p.startswith("__anon"))
        name = f"{scope}::{tag['name']}" if scope else tag["name"]
        rows.append((n, name, f"{tag['path']}:{tag['line']}"))
for n, name, where in sorted(rows, reverse=True):
    print(f"{n:5d}  {name:55s} {where}")
print(f"{len(rows)} functions of {min_lines}+ lines")
