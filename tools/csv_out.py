"""Writing a benchmark's CSV: comment lines, then a header and one line per row (dicts with the same keys),
atomically (a temporary file renamed when complete), creating the folder if needed."""
import os


def write_csv(path, comments, rows):
    tmp = path + ".tmp"
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with open(tmp, "w") as f:
        for c in comments:
            f.write(f"# {c}\n")
        keys = list(rows[0].keys())
        f.write(",".join(keys) + "\n")
        for r in rows:
            f.write(",".join(str(r[k]) for k in keys) + "\n")
    os.replace(tmp, path)
