"""Reading a project CSV log for the analysis scripts in this directory.

A log is a header row of column names, then one row per tick; an empty cell
means "not measured". `read_columns` returns the columns asked for as lists
of floats. A script beside this file imports it so that it runs from any
directory:

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import logcsv

    cols = logcsv.read_columns(path, ["t_s", "i_ref_a"], optional=["fault_code"], min_rows=3)
    t, fault = cols["t_s"], cols.get("fault_code")

* A required column must be in the header and measured on every row (as
  `host-sim`'s own reader, `host-sim/src/log`, wants its required columns),
  unless it is also in `allow_empty`: then its empty cells read as
  float("nan").
* An optional column may be absent (it is then absent from the dict) or
  have empty cells, which read as float("nan").

Any problem ends the script with one message naming the file, the line
(1-based, the header is line 1) and the column, in `host-sim`'s form
`FILE:LINE: column "NAME": what`: a missing required column, an empty cell
in a required column, a cell that is not a finite number (NaN and inf
included, as `host-sim` refuses them), a row with fewer fields
than the header, and fewer rows than `min_rows`. Blank lines at the end of
the file are ignored; a blank line before another row is a row cut short
(in a one-column log, a row not measured). A row longer than the header is
read, its extra cells ignored.

Standard library only.
"""

import csv
import math
import sys

MAX_QUOTED_CHARS = 40


def quoted(text):
    """`text` in double quotes on one line, cut after MAX_QUOTED_CHARS
    characters."""
    text = text.replace("\r", "\\r").replace("\n", "\\n")
    if len(text) > MAX_QUOTED_CHARS:
        return f'"{text[:MAX_QUOTED_CHARS]}..." ({len(text)} characters)'
    return f'"{text}"'


def fail(path, what, line=None, column=None):
    """Ends the script with `FILE:LINE: column "NAME": what`."""
    where = f"{path}:{line}" if line is not None else f"{path}"
    col = f"column {quoted(column)}: " if column is not None else ""
    sys.exit(f"{where}: {col}{what}")


def parse(path, row, line, header, wanted):
    """Appends one data row's cells to the lists of `wanted`, (name, index,
    required, values) for each column read."""
    if len(row) < len(header):
        fail(path, f"row has {len(row)} fields, the header has {len(header)} (row cut short?)",
             line=line, column=header[len(row)])
    for name, i, required, values in wanted:
        try:
            value = float(row[i])
            if not math.isfinite(value):
                fail(path, f"{quoted(row[i].strip())} is not a finite number", line=line,
                     column=name)
            values.append(value)
        except ValueError:
            cell = row[i].strip()
            if cell:
                fail(path, f"{quoted(cell)} is not a number", line=line, column=name)
            if required:
                fail(path, "empty cell (not measured) in a required column", line=line, column=name)
            values.append(math.nan)


def read_columns(path, required, optional=(), min_rows=0, allow_empty=()):
    """The columns `required` and those of `optional` the file has, as
    {name: [float, ...]} (one value per data row); see the module's
    docstring for what is checked. Exits on the first problem."""
    required = list(required)
    optional = [c for c in optional if c not in required]
    try:
        f = open(path, newline="", encoding="utf-8-sig")
    except OSError as e:
        fail(path, e.strerror or str(e))
    with f:
        reader = csv.reader(f)
        try:
            header = [name.strip() for name in next(reader, [])]
            if not any(header):
                fail(path, "no header line (empty file)", line=1)
            asked = required + [c for c in optional if c in header]
            for name in asked:
                if header.count(name) > 1:
                    fail(path, "column name appears twice", line=1, column=name)
            missing = [c for c in required if c not in header]
            if len(missing) == 1:
                fail(path, "required column is missing", line=1, column=missing[0])
            if missing:
                names = ", ".join(quoted(c) for c in missing)
                fail(path, f"columns {names}: required columns are missing", line=1)
            cols = {c: [] for c in asked}
            measured = [c for c in required if c not in allow_empty]
            wanted = [(c, header.index(c), c in measured, cols[c]) for c in asked]
            line, rows, blank_lines = reader.line_num, 0, []
            for row in reader:
                first, line = line + 1, reader.line_num
                if not row or (len(row) == 1 and not row[0].strip()):
                    # At the end of the file, nothing; before another row,
                    # a row of one empty cell.
                    blank_lines.append(first)
                    continue
                if blank_lines and len(header) > 1:
                    fail(path, f"blank line, the header has {len(header)} fields (row cut short?)",
                         line=blank_lines[0], column=header[0])
                for at in blank_lines:
                    parse(path, [""], at, header, wanted)
                rows += len(blank_lines) + 1
                blank_lines = []
                parse(path, row, first, header, wanted)
        except csv.Error as e:
            fail(path, f"not a CSV log ({e})", line=reader.line_num)
        except UnicodeDecodeError as e:
            fail(path, f"not UTF-8 text ({e.reason})")
    if rows < min_rows:
        fail(path, f"{rows} data rows, at least {min_rows} needed")
    return cols
