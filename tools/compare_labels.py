"""Count label changes between two maps of the same launches:
python tools/compare_labels.py OLD NEW"""
import collections
import sys

import xarray as xr


def words(ds):
    names = ds.label.attrs["flag_meanings"].split()
    return [names[int(c)] for c in ds.label.values.ravel()]


def main(old_path, new_path):
    old, new = xr.open_dataset(old_path), xr.open_dataset(new_path)
    pairs = collections.Counter(zip(words(old), words(new)))
    changed = sum(v for (a, b), v in pairs.items() if a != b)
    print(f"{changed} of {sum(pairs.values())} launches changed label")
    for (a, b), v in sorted(pairs.items(), key=lambda kv: -kv[1]):
        if a != b:
            print(f"  {a:>14s} -> {b:<14s} {v}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
