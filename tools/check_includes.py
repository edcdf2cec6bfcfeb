#!/usr/bin/env python3
"""Module boundary check: physics/, collision/ and render/ include none of each other, nor engine/.

usage: tools/check_includes.py [ROOT]   (ROOT: the repository, default the one holding this script)

Scans every C/C++ source and header under ROOT/physics, ROOT/collision and ROOT/render for an #include
("..." or <...>, also through ../) of another of those folders or of engine/, prints each as
FILE:LINE: INCLUDE: WHO must not include WHAT, and exits 1 if there is any (0 otherwise). The build enforces
the same rule (each library exports only its own folder); this names the offending line.
"""
import os
import re
import sys

MODULES = ("physics", "collision", "render")
FORBIDDEN = MODULES + ("engine",)
EXTENSIONS = (".cpp", ".hpp", ".h", ".cc", ".hh", ".cxx", ".hxx", ".inl", ".ipp", ".tpp")
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])((?:\.\./|\./)*)([A-Za-z0-9_]+)/([^>"]*)[>"]')


def violations(root):
    found = []
    for module in MODULES:
        top = os.path.join(root, module)
        for dirpath, dirnames, filenames in os.walk(top):
            dirnames.sort()
            for name in sorted(filenames):
                if not name.endswith(EXTENSIONS):
                    continue
                path = os.path.join(dirpath, name)
                with open(path, encoding="utf-8", errors="replace") as f:
                    for number, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if m and m.group(3) in FORBIDDEN and m.group(3) != module:
                            close = ">" if m.group(1) == "<" else '"'
                            include = f"#include {m.group(1)}{m.group(2)}{m.group(3)}/{m.group(4)}{close}"
                            found.append((os.path.relpath(path, root), number, include, module, m.group(3)))
    return found


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), ".."))
    for module in MODULES:
        if not os.path.isdir(os.path.join(root, module)):
            print(f"check_includes: no folder {module}/ under {root}", file=sys.stderr)
            return 2
    found = violations(root)
    for path, number, include, who, what in found:
        print(f"{path}:{number}: {include}: {who} must not include {what}")
    if found:
        print(f"{len(found)} forbidden includes (physics, collision and render include only themselves; "
              "only engine combines them)")
        return 1
    print("check_includes: physics, collision and render include none of each other nor engine")
    return 0


if __name__ == "__main__":
    sys.exit(main())
