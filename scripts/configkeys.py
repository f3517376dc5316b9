"""One number from a project TOML file (a configuration `host-sim` reads or
writes) for the analysis scripts in this directory, by its key alone: the
configuration's keys are unique across its tables. A script beside this
file imports it as it imports `logcsv`:

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import configkeys

    text = open(path).read()
    cutoff = configkeys.value(path, text, "cutoff_rad_s")

A key the file does not hold ends the script with one message naming the
file and the key. Standard library only.
"""

import re
import sys


def value(path, text, key):
    """The number `key = ...` in `text` (the contents of `path`)."""
    m = re.search(r"\n" + key + r" = ([0-9.eE+-]+)", text)
    if not m:
        sys.exit(f"{path}: no {key}")
    return float(m.group(1))
