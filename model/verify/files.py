"""The files ``verify`` reads and writes: .npz, a directory of NAME.npy files, CSV and JSON.

Pure numpy (no dolfinx), so that a C++, Fortran or GPU code can write a plain text file and have it
checked. Every format holds the same named quantities (N samples):

    F            (N,3,3)   deformation gradients (required)
    psi          (N,)      energy density
    P            (N,3,3)   first Piola-Kirchhoff stress
    PK2          (N,3,3) or Voigt (N,6)   second Piola-Kirchhoff stress (``S`` is the shape-target field)
    sigma        (N,3,3) or Voigt (N,6)   Cauchy stress
    A            the tangent in its layout (model.verify.layouts): (N,3,3,3,3) ijkl, (N,9,9) hessian9-col
                 or -row, (N,6,6) voigt-spatial, abaqus-ddsdde or voigt-material
    S, a0, s0, alpha   the law's fields, shapes forms.metadata.FIELD_SHAPES: (N,3,3), (N,3), (N,3), (N,)
    labels       (N,) strings, the kind of each sample
    material     the law's name (text)
    params_json  the parameters as a JSON object (text)
    layout       the tangent's layout (text), one of model.verify.layouts.TANGENT_LAYOUTS

Formats (chosen by the path: a directory, or the suffix .npz, .csv, .json):

- ``.npz``: one array per quantity (``numpy.savez``), material / params_json / layout as 0-d strings
  (what ``verify emit`` has always written).
- a directory: one ``NAME.npy`` per quantity (labels as a unicode array), and ``meta.json`` =
  {"material": ..., "params": {...}, "layout": ...} (each key optional).
- ``.csv``: one row per sample; optional leading lines ``# material: NAME``, ``# params: {JSON}``,
  ``# layout: LAYOUT``; then a header naming the columns, any order:
  F11 F12 F13 F21 ... F33 (row-major: i, then j), psi, P11..P33, PK2_11..PK2_33 or the Voigt six
  PK2_11 PK2_22 PK2_33 PK2_12 PK2_13 PK2_23, sigma11..sigma33 or sigma11 sigma22 sigma33 sigma12 sigma13
  sigma23, the tangent as A1111 A1112 ... A3333 (i, j, k, l 1-based, l fastest), H_0_0 ... H_8_8 (9x9,
  0-based, row a, column b) or D11 ... D66 (6x6, 1-based Voigt indices), fields S11..S33, a01..a03,
  s01..s03, alpha, and ``label`` (text). Numbers as C's printf("%.17g") writes them; nan, inf allowed.
- ``.json``: {"material": ..., "params": {...}, "layout": ..., "F": [[[...]]], "psi": [...], ...}: each
  quantity a nested list of the shape above (NaN, Infinity as Python's json writes them).

Errors are one line (``FileFormatError``, a ValueError) naming the file and the array or column:
unknown suffix, bad JSON (with line and column), a sample count that differs from F's, a shape no
layout has, a non-numeric CSV cell.
"""

from __future__ import annotations

import csv
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from forms.metadata import FIELD_SHAPES
from model.verify.layouts import TANGENT_LAYOUTS, TANGENT_SHAPES, VOIGT_ORDER

FORMATS = ("npz", "npy", "csv", "json")
SUFFIXES = {".npz": "npz", ".csv": "csv", ".json": "json"}
TEXT_KEYS = ("material", "params_json", "layout", "emit_json")  # emit_json: what emit moved or dropped (.npz only)
#: the key of each stress measure in a file (S is the shape-target field, so the second Piola-Kirchhoff is PK2)
STRESS_KEYS = {"P": "P", "S": "PK2", "sigma": "sigma"}
META_FILE = "meta.json"

Arrays = dict[str, Any]


class FileFormatError(ValueError):
    """A file ``verify`` cannot read or write; the message is one line naming the file and the array or column."""


# --- shapes ----------------------------------------------------------------------------------------

def _shape_text(shape: tuple[int, ...]) -> str:
    return "(N" + "".join(f", {d}" for d in shape) + ")"


def _known_shapes() -> dict[str, list[tuple[int, ...]]]:
    """The allowed per-sample shapes of each numeric quantity."""
    shapes: dict[str, list[tuple[int, ...]]] = {"F": [(3, 3)], "psi": [()], "P": [(3, 3)], "PK2": [(3, 3), (6,)],
                                                "sigma": [(3, 3), (6,)],
                                                "A": [(3, 3, 3, 3), (9, 9), (6, 6)]}
    for name, shape in FIELD_SHAPES.items():
        shapes[name] = [tuple(shape)]
    return shapes


def _validate(path: Path, arrays: Arrays, layout: str | None) -> Arrays:
    """Check names, sample counts and shapes; returns the arrays with numeric ones as float64."""
    if "F" not in arrays:
        raise FileFormatError(f"{path}: no F (the deformation gradients are required)")
    out: Arrays = {}
    for key in TEXT_KEYS:
        if key in arrays and arrays[key] is not None:
            out[key] = str(arrays[key])
    if "params_json" in out:
        try:
            params = json.loads(out["params_json"])
        except json.JSONDecodeError as err:
            raise FileFormatError(f"{path}: params_json is not valid JSON at line {err.lineno} column {err.colno}: "
                                  f"{err.msg}") from None
        if not isinstance(params, dict):
            raise FileFormatError(f"{path}: params_json must be a JSON object {{\"key\": value}}, "
                                  f"not {type(params).__name__}")
    file_layout = out.get("layout")
    if file_layout is not None and file_layout not in TANGENT_LAYOUTS:
        raise FileFormatError(f"{path}: layout {file_layout!r} is unknown; known: {', '.join(TANGENT_LAYOUTS)}")
    if layout is not None:
        if layout not in TANGENT_LAYOUTS:
            raise FileFormatError(f"layout {layout!r} is unknown; known: {', '.join(TANGENT_LAYOUTS)}")
        if file_layout is not None and file_layout != layout:
            raise FileFormatError(f"{path}: the file's layout is {file_layout}, not {layout}")
        out["layout"] = layout
    shapes = _known_shapes()
    F = _numeric(path, "F", arrays["F"])
    if F.ndim != 3 or F.shape[1:] != (3, 3):
        raise FileFormatError(f"{path}: F: shape {F.shape}, needs (N, 3, 3)")
    n = len(F)
    out["F"] = F
    for key, value in arrays.items():
        if key in TEXT_KEYS or key == "F" or value is None:
            continue
        if key == "labels":
            labels = np.asarray(value)
            if labels.ndim != 1 or len(labels) != n:
                raise FileFormatError(f"{path}: labels: {_count(labels)} samples, F has {n}")
            out[key] = labels.astype(str)
            continue
        array = _numeric(path, key, value)
        if array.ndim == 0 or len(array) != n:
            raise FileFormatError(f"{path}: {key}: {_count(array)} samples, F has {n}")
        if key == "A" and out.get("layout") is not None:
            need = TANGENT_SHAPES[out["layout"]]
            if array.shape[1:] != need:
                raise FileFormatError(f"{path}: A (the tangent): shape {array.shape}, {out['layout']} needs "
                                      f"{_shape_text(need)}")
        elif key in shapes and array.shape[1:] not in shapes[key]:
            allowed = " or ".join(_shape_text(s) for s in shapes[key])
            what = "A (the tangent)" if key == "A" else key
            raise FileFormatError(f"{path}: {what}: shape {array.shape}, needs {allowed}")
        out[key] = array
    return out


def _count(array: np.ndarray) -> int:
    return len(array) if np.ndim(array) else 0


def _numeric(path: Path, key: str, value: Any) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise FileFormatError(f"{path}: {key}: not an array of numbers") from None
    return array


def file_format(path: str | Path, fmt: str | None = None) -> str:
    """The format of ``path``: ``fmt`` if given, "npy" for a directory, else by suffix (.npz, .csv, .json)."""
    path = Path(path)
    if fmt is not None:
        if fmt not in FORMATS:
            raise FileFormatError(f"{path}: format {fmt!r} is unknown; known: {', '.join(FORMATS)}")
        return fmt
    if path.is_dir():
        return "npy"
    if path.suffix.lower() in SUFFIXES:
        return SUFFIXES[path.suffix.lower()]
    raise FileFormatError(f"{path}: unknown file format (suffix {path.suffix!r}); known: .npz, .csv, .json, "
                          "or a directory of NAME.npy files")


def formats_help() -> str:
    """The file formats, for ``--help``."""
    return ("  .npz             one array per quantity (F, psi, P, PK2, sigma, A, S, a0, s0, alpha, labels, material,\n"
            "                   params_json, layout)\n"
            "  DIRECTORY        one NAME.npy per quantity, meta.json = {material, params, layout}\n"
            "  .csv             one row per sample; header F11..F33 (row-major), psi, P11..P33, sigma11.., PK2_11..,\n"
            "                   A1111..A3333 | H_0_0..H_8_8 | D11..D66, S11.., a01.., s01.., alpha, label;\n"
            "                   optional first lines '# material: NAME', '# params: {JSON}', '# layout: LAYOUT'\n"
            "  .json            {\"material\": .., \"params\": {..}, \"layout\": .., \"F\": [[[..]]], ...}")


# --- reading ---------------------------------------------------------------------------------------

def read_arrays(path: str | Path, layout: str | None = None) -> Arrays:
    """The quantities of a file (see the module docstring): numeric arrays as float64, labels as str,
    material / params_json / layout as str (only those present). ``layout``, when given, must agree with
    the file's and fixes the tangent's shape."""
    path = Path(path)
    if not path.exists():
        written = output_path(path)[0]
        if written != path and written.exists():  # emit --out xx wrote xx.npz
            raise FileFormatError(f"{path}: no such file or directory; {written} exists (emit --out {path.name} "
                                  f"writes {written.name}: a path without .npz, .csv or .json gets .npz)")
        raise FileFormatError(f"{path}: no such file or directory")
    fmt = file_format(path)
    reader = {"npz": _read_npz, "npy": _read_npy_dir, "csv": _read_csv, "json": _read_json}[fmt]
    return _validate(path, reader(path), layout)


def _json_loads(path: Path, text: str, what: str = "") -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise FileFormatError(f"{path}: {what}not valid JSON at line {err.lineno} column {err.colno}: "
                              f"{err.msg}") from None


def _params_text(path: Path, params: Any) -> str:
    if not isinstance(params, dict):
        raise FileFormatError(f"{path}: params must be a JSON object {{\"key\": value}}, not {type(params).__name__}")
    return json.dumps(params, sort_keys=True)


def _read_npz(path: Path) -> Arrays:
    try:
        with np.load(path, allow_pickle=False) as data:
            content = {key: data[key] for key in data.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as err:
        raise FileFormatError(f"{path}: not a readable .npz file ({err})") from None
    for key in TEXT_KEYS:
        if key in content:
            content[key] = str(content[key])
    return content


def _read_meta(path: Path, meta: Any) -> Arrays:
    if not isinstance(meta, dict):
        raise FileFormatError(f"{path}: must be a JSON object, not {type(meta).__name__}")
    out: Arrays = {}
    for key, value in meta.items():
        if key == "params":
            out["params_json"] = _params_text(path, value)
        elif key in ("material", "layout"):
            out[key] = str(value)
        else:
            raise FileFormatError(f"{path}: unknown key {key!r} (known: material, params, layout)")
    return out


def _read_npy_dir(path: Path) -> Arrays:
    out: Arrays = {}
    for file in sorted(path.glob("*.npy")):
        try:
            out[file.stem] = np.load(file, allow_pickle=False)
        except (ValueError, OSError, EOFError) as err:
            raise FileFormatError(f"{file}: not a readable .npy file ({err})") from None
    meta = path / META_FILE
    if meta.exists():
        out.update(_read_meta(meta, _json_loads(meta, meta.read_text())))
    return out


def _read_json(path: Path) -> Arrays:
    content = _json_loads(path, path.read_text())
    if not isinstance(content, dict):
        raise FileFormatError(f"{path}: must be a JSON object {{\"F\": [...], ...}}, not {type(content).__name__}")
    out: Arrays = {}
    for key, value in content.items():
        if key == "params":
            out["params_json"] = _params_text(path, value)
        elif key in ("material", "layout", "params_json"):
            out[key] = str(value)
        else:
            out[key] = value
    return out


# --- CSV columns -----------------------------------------------------------------------------------

def _matrix_columns(prefix: str) -> list[str]:
    return [f"{prefix}{i + 1}{j + 1}" for i in range(3) for j in range(3)]


def _voigt_columns(prefix: str) -> list[str]:
    return [f"{prefix}{i + 1}{j + 1}" for i, j in VOIGT_ORDER]


def csv_columns() -> dict[str, list[tuple[list[str], tuple[int, ...]]]]:
    """Per quantity, its column variants (names, per-sample shape), the first complete one is taken."""
    groups: dict[str, list[tuple[list[str], tuple[int, ...]]]] = {
        "F": [(_matrix_columns("F"), (3, 3))],
        "psi": [(["psi"], ())],
        "P": [(_matrix_columns("P"), (3, 3))],
        "PK2": [(_matrix_columns("PK2_"), (3, 3)), (_voigt_columns("PK2_"), (6,))],
        "sigma": [(_matrix_columns("sigma"), (3, 3)), (_voigt_columns("sigma"), (6,))],
        "A": [([f"A{i + 1}{j + 1}{k + 1}{m + 1}" for i in range(3) for j in range(3) for k in range(3)
                for m in range(3)], (3, 3, 3, 3)),
              ([f"H_{a}_{b}" for a in range(9) for b in range(9)], (9, 9)),
              ([f"D{a + 1}{b + 1}" for a in range(6) for b in range(6)], (6, 6))],
    }
    for name, shape in FIELD_SHAPES.items():
        if shape == (3, 3):
            columns = _matrix_columns(name)
        elif shape == (3,):
            columns = [f"{name}{i + 1}" for i in range(3)]
        else:
            columns = [name]
        groups[name] = [(columns, tuple(shape))]
    return groups


def _read_csv(path: Path) -> Arrays:
    meta: Arrays = {}
    lines = path.read_text().splitlines()
    start = 0
    while start < len(lines) and (lines[start].startswith("#") or not lines[start].strip()):
        text = lines[start].lstrip("#").strip()
        key, sep, value = text.partition(":")
        key, value = key.strip(), value.strip()
        if sep and key == "params":
            meta["params_json"] = _params_text(path, _json_loads(path, value, f"line {start + 1}: params is "))
        elif sep and key in ("material", "layout"):
            meta[key] = value
        start += 1
    rows = list(csv.reader(lines[start:]))
    if not rows:
        raise FileFormatError(f"{path}: no header line (column names F11 ... F33, ...)")
    header = [name.strip() for name in rows[0]]
    duplicates = sorted({name for name in header if header.count(name) > 1})
    if duplicates:
        raise FileFormatError(f"{path}: column {duplicates[0]} appears twice")
    body = rows[1:]
    for number, row in enumerate(body):
        if len(row) != len(header):
            raise FileFormatError(f"{path}: line {start + 2 + number} has {len(row)} cells, the header {len(header)}")
    index = {name: position for position, name in enumerate(header)}
    used: set[str] = set()
    out: Arrays = dict(meta)
    for key, variants in csv_columns().items():
        chosen = next((v for v in variants if all(c in index for c in v[0])), None)
        if chosen is None:
            present = [c for v in variants for c in v[0] if c in index]
            if present:
                best = max(variants, key=lambda v: sum(c in index for c in v[0]))[0]
                missing = [c for c in best if c not in index]
                raise FileFormatError(f"{path}: {key}: column{'s' if len(missing) > 1 else ''} "
                                      f"{', '.join(missing[:6])}{' ...' if len(missing) > 6 else ''} missing "
                                      f"({key} needs {best[0]} ... {best[-1]})")
            continue
        columns, shape = chosen
        values = np.empty((len(body), len(columns)))
        for j, column in enumerate(columns):
            for number, row in enumerate(body):
                cell = row[index[column]].strip()
                try:
                    values[number, j] = float(cell)
                except ValueError:
                    raise FileFormatError(f"{path}: line {start + 2 + number}, column {column}: {cell!r} is not "
                                          "a number") from None
        out[key] = values.reshape(len(body), *shape)
        used.update(columns)
    if "label" in index:
        out["labels"] = np.array([row[index["label"]] for row in body], dtype=str)
        used.add("label")
    unknown = [name for name in header if name not in used]
    if unknown:
        raise FileFormatError(f"{path}: unknown column {unknown[0]!r} (known: F11..F33, psi, P11..P33, "
                              "PK2_11.., sigma11.., A1111.., H_0_0.., D11.., fields S11.., a01.., s01.., alpha, label)")
    return out


# --- writing ---------------------------------------------------------------------------------------

def output_path(path: str | Path, fmt: str | None = None) -> tuple[Path, str]:
    """(the path written, its format): the path as given when ``fmt`` is given, it is a directory (npy) or
    its suffix is known; else the path with ".npz" appended."""
    path = Path(path)
    if fmt is not None or path.is_dir() or path.suffix.lower() in SUFFIXES:
        return path, file_format(path, fmt)
    return path.with_name(path.name + ".npz"), "npz"


def write_arrays(path: str | Path, arrays: Arrays, fmt: str | None = None) -> Path:
    """Write ``arrays`` (the quantities of the module docstring) and return the path written (see ``output_path``).

    ``fmt`` is "npz", "npy" (a directory), "csv" or "json"; by default the suffix decides.
    """
    target, fmt = output_path(path, fmt)
    data = _validate(target, arrays, None)
    if fmt == "npz":
        target.parent.mkdir(parents=True, exist_ok=True)
        with open(target, "wb") as stream:  # a file object: numpy.savez would append ".npz" to a name
            np.savez(stream, **{k: (np.array(v) if isinstance(v, str) else v) for k, v in data.items()})
    elif fmt == "npy":
        target.mkdir(parents=True, exist_ok=True)
        for key, value in data.items():
            if key not in TEXT_KEYS:
                np.save(target / f"{key}.npy", value)
        meta = _meta(data)
        if meta:
            (target / META_FILE).write_text(json.dumps(meta, indent=1) + "\n")
    elif fmt == "json":
        target.parent.mkdir(parents=True, exist_ok=True)
        content = _meta(data)
        content.update({k: v.tolist() for k, v in data.items() if k not in TEXT_KEYS})
        target.write_text(json.dumps(content) + "\n")
    else:
        target.parent.mkdir(parents=True, exist_ok=True)
        _write_csv(target, data)
    return target


def _meta(data: Arrays) -> Arrays:
    meta: Arrays = {}
    if "material" in data:
        meta["material"] = data["material"]
    if "params_json" in data:
        meta["params"] = json.loads(data["params_json"])
    if "layout" in data:
        meta["layout"] = data["layout"]
    return meta


def _write_csv(target: Path, data: Arrays) -> None:
    groups = csv_columns()
    header: list[str] = []
    blocks: list[np.ndarray] = []
    n = len(data["F"])
    for key in data:
        if key not in groups and key not in TEXT_KEYS and key != "labels":
            raise FileFormatError(f"{target}: {key} has no CSV columns (known: {', '.join(groups)}, labels)")
    for key, variants in groups.items():
        if key not in data:
            continue
        value = data[key]
        columns = next(c for c, shape in variants if value.shape[1:] == shape)
        header += columns
        blocks.append(value.reshape(n, -1))
    lines = [f"# {key}: {value}" for key, value in (("material", data.get("material")),
                                                     ("params", data.get("params_json")),
                                                     ("layout", data.get("layout"))) if value is not None]
    table = np.concatenate(blocks, axis=1)
    with open(target, "w", newline="") as stream:
        for line in lines:
            stream.write(line + "\n")
        writer = csv.writer(stream)
        writer.writerow(header + (["label"] if "labels" in data else []))
        for row in range(n):
            cells = [repr(float(x)) for x in table[row]]
            writer.writerow(cells + ([str(data["labels"][row])] if "labels" in data else []))


__all__ = ["FORMATS", "STRESS_KEYS", "FileFormatError", "csv_columns", "file_format", "formats_help", "output_path",
           "read_arrays", "write_arrays"]
