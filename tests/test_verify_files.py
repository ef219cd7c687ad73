"""The files verify reads and writes (model/verify/files.py): every format's round trip, a CSV written by
hand as a C++ or Fortran code would, the path written, and each error message."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from model.verify.files import FileFormatError, read_arrays, write_arrays

N = 5


def quantities(tangent_shape: tuple[int, ...], stress_shape: tuple[int, ...], seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    data = {
        "F": rng.standard_normal((N, 3, 3)),
        "psi": rng.standard_normal(N),
        "P": rng.standard_normal((N, 3, 3)),
        "sigma": rng.standard_normal((N, *stress_shape)),
        "PK2": rng.standard_normal((N, *stress_shape)),
        "A": rng.standard_normal((N, *tangent_shape)) * 10.0 ** rng.integers(-300, 300, (N, *tangent_shape)),
        "S": rng.standard_normal((N, 3, 3)),
        "a0": rng.standard_normal((N, 3)),
        "s0": rng.standard_normal((N, 3)),
        "alpha": rng.uniform(0, 1, N),
        "labels": np.array(["identity", "rotation, twisted", 'quote "q"', "nearly_flat", "inverted_random"]),
        "material": "muscle",
        "params_json": json.dumps({"mu": 1.5, "isotropic": "stvk"}),
        "layout": {(3, 3, 3, 3): "ijkl", (9, 9): "hessian9-col", (6, 6): "abaqus-ddsdde"}[tangent_shape],
    }
    data["psi"][2] = np.nan  # e.g. ln J at J < 0: a user's file may hold it
    data["A"][1, 0, 0] = np.inf
    return data


def assert_same(back: dict, data: dict) -> None:
    assert sorted(back) == sorted(data)
    for key, value in data.items():
        if key == "params_json":
            assert json.loads(back[key]) == json.loads(value)
        elif isinstance(value, str):
            assert back[key] == value, key
        elif key == "labels":
            assert [str(x) for x in back[key]] == [str(x) for x in value]
        else:
            assert back[key].dtype == np.float64 and back[key].shape == value.shape, key
            np.testing.assert_array_equal(back[key], value, err_msg=key)  # bit for bit, NaN and inf included


@pytest.mark.parametrize("shapes", [((3, 3, 3, 3), (3, 3)), ((9, 9), (3, 3)), ((6, 6), (6,))])
@pytest.mark.parametrize("name, fmt", [("ref.npz", None), ("ref.csv", None), ("ref.json", None), ("ref", "npy")])
def test_round_trip(name: str, fmt: str | None, shapes, tmp_path: Path) -> None:
    data = quantities(*shapes)
    written = write_arrays(tmp_path / name, data, fmt)
    assert written == tmp_path / name
    assert written.is_dir() if fmt == "npy" else written.is_file()
    assert_same(read_arrays(written), data)


def test_path_written(tmp_path: Path) -> None:
    data = {"F": np.tile(np.eye(3), (2, 1, 1)), "psi": np.zeros(2)}
    assert write_arrays(tmp_path / "xx", data) == tmp_path / "xx.npz"  # no known suffix: .npz appended, and said
    assert (tmp_path / "xx.npz").is_file() and not (tmp_path / "xx").exists()
    assert write_arrays(tmp_path / "mine.dat", data, "npz") == tmp_path / "mine.dat"  # exactly the path given
    assert (tmp_path / "mine.dat").is_file() and not (tmp_path / "mine.dat.npz").exists()
    np.testing.assert_array_equal(read_arrays(tmp_path / "xx.npz")["F"], data["F"])
    (tmp_path / "dir").mkdir()
    assert write_arrays(tmp_path / "dir", data) == tmp_path / "dir"  # an existing directory: NAME.npy files
    assert sorted(p.name for p in (tmp_path / "dir").iterdir()) == ["F.npy", "psi.npy"]


def test_handwritten_csv(tmp_path: Path) -> None:
    """Columns in any order, spaces, %.17g numbers, the Voigt Cauchy stress, a 6x6 DDSDDE, no label."""
    rng = np.random.default_rng(3)
    F = rng.standard_normal((3, 3, 3))
    sigma = rng.standard_normal((3, 6))
    D = rng.standard_normal((3, 6, 6))
    header = ["sigma11", "sigma22", "sigma33", "sigma12", "sigma13", "sigma23"]
    header += [f"D{a}{b}" for a in range(1, 7) for b in range(1, 7)]
    header += [f"F{i}{j}" for i in range(1, 4) for j in range(1, 4)]
    lines = ["# written by a Fortran UMAT driver", "# material: neo_hookean", '# params: {"mu": 2, "lmbda": 3}',
             "# layout: abaqus-ddsdde", ", ".join(header)]
    for n in range(3):
        cells = list(sigma[n]) + list(D[n].reshape(-1)) + list(F[n].reshape(-1))
        lines.append(", ".join(f"{x:.17g}" for x in cells))
    path = tmp_path / "umat.csv"
    path.write_text("\n".join(lines) + "\n")
    back = read_arrays(path)
    assert back["material"] == "neo_hookean" and json.loads(back["params_json"]) == {"mu": 2, "lmbda": 3}
    assert back["layout"] == "abaqus-ddsdde"
    np.testing.assert_array_equal(back["F"], F)  # F11 F12 F13 F21 ...: row-major
    np.testing.assert_array_equal(back["sigma"], sigma)
    np.testing.assert_array_equal(back["A"], D)  # D14 is row 0, column 3
    assert sorted(back) == ["A", "F", "layout", "material", "params_json", "sigma"]


def test_handwritten_json_and_hessian_columns(tmp_path: Path) -> None:
    H = np.arange(81.0).reshape(1, 9, 9)
    path = tmp_path / "hobak.json"
    path.write_text(json.dumps({"material": "stvk", "params": {"mu": 1}, "layout": "hessian9-col",
                                "F": np.eye(3)[None].tolist(), "A": H.tolist()}))
    back = read_arrays(path)
    np.testing.assert_array_equal(back["A"], H)
    written = write_arrays(tmp_path / "hobak.csv", back)
    header = [line for line in written.read_text().splitlines() if not line.startswith("#")][0].split(",")
    assert header[9:12] == ["H_0_0", "H_0_1", "H_0_2"] and header[-1] == "H_8_8"
    np.testing.assert_array_equal(read_arrays(written)["A"], H)


def error(path: Path, **kwargs) -> str:
    with pytest.raises(FileFormatError) as info:
        read_arrays(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_errors(tmp_path: Path) -> None:
    F = np.tile(np.eye(3), (30, 1, 1))
    unknown = tmp_path / "mine.txt"
    unknown.write_text("F11\n")
    assert error(unknown) == (f"{unknown}: unknown file format (suffix '.txt'); known: .npz, .csv, .json, or a "
                              "directory of NAME.npy files")
    assert error(tmp_path / "nope.npz") == f"{tmp_path / 'nope.npz'}: no such file or directory"

    bad_json = tmp_path / "bad.json"
    bad_json.write_text('{"F": [[[1, 0, 0], [0, 1, 0], [0, 0, 1]]],\n "psi": [1 2]}')
    assert error(bad_json).startswith(f"{bad_json}: not valid JSON at line 2 column 12: Expecting ',' delimiter")

    count = tmp_path / "count.npz"
    np.savez(count, F=F, P=np.zeros((29, 3, 3)))
    assert error(count) == f"{count}: P: 29 samples, F has 30"

    shape = tmp_path / "shape.npz"
    np.savez(shape, F=F, A=np.zeros((30, 9, 8)), layout=np.array("hessian9-col"))
    assert error(shape) == f"{shape}: A (the tangent): shape (30, 9, 8), hessian9-col needs (N, 9, 9)"
    no_layout = tmp_path / "no_layout.npz"
    np.savez(no_layout, F=F, A=np.zeros((30, 9, 8)))
    assert "A (the tangent): shape (30, 9, 8), needs (N, 3, 3, 3, 3) or (N, 9, 9) or (N, 6, 6)" in error(no_layout)
    ok = tmp_path / "ok.npz"
    np.savez(ok, F=F, A=np.zeros((30, 6, 6)))
    assert error(ok, layout="ijkl") == f"{ok}: A (the tangent): shape (30, 6, 6), ijkl needs (N, 3, 3, 3, 3)"
    assert read_arrays(ok, layout="voigt-material")["layout"] == "voigt-material"
    np.savez(ok, F=F, layout=np.array("hessian9"))
    assert error(ok).startswith(f"{ok}: layout 'hessian9' is unknown; known: ijkl, hessian9-col")

    params = tmp_path / "params.npz"
    np.savez(params, F=F, material=np.array("stvk"), params_json=np.array('{"mu": 1,'))
    assert error(params).startswith(f"{params}: params_json is not valid JSON at line 1 column 10: ")

    no_F = tmp_path / "no_F.json"
    no_F.write_text('{"psi": [1.0]}')
    assert error(no_F) == f"{no_F}: no F (the deformation gradients are required)"

    header = ",".join(f"F{i}{j}" for i in range(1, 4) for j in range(1, 4)) + ",psi,P11"
    cells = "1,0,0,0,1,0,0,0,1"
    csv_missing = tmp_path / "missing.csv"
    csv_missing.write_text(header + "\n" + cells + ",0.5,0\n")
    assert error(csv_missing) == (f"{csv_missing}: P: columns P12, P13, P21, P22, P23, P31 ... missing "
                                  "(P needs P11 ... P33)")
    csv_text = tmp_path / "text.csv"
    csv_text.write_text("# material: stvk\n" + header[:-4] + "\n" + cells + ",0.5\n" + cells + ",abc\n")
    assert error(csv_text) == f"{csv_text}: line 4, column psi: 'abc' is not a number"
    csv_cells = tmp_path / "cells.csv"
    csv_cells.write_text(header[:-4] + "\n" + cells + "\n")
    assert error(csv_cells) == f"{csv_cells}: line 2 has 9 cells, the header 10"
    csv_unknown = tmp_path / "unknown.csv"
    csv_unknown.write_text(header[:-4] + ",Q11\n" + cells + ",0.5,1\n")
    assert error(csv_unknown).startswith(f"{csv_unknown}: unknown column 'Q11' (known: F11..F33, psi")
    csv_params = tmp_path / "params.csv"
    csv_params.write_text("# params: {mu: 1}\n" + header[:-4] + "\n" + cells + ",0.5\n")
    assert error(csv_params).startswith(f"{csv_params}: line 1: params is not valid JSON at line 1 column 2: ")

    directory = tmp_path / "npy"
    directory.mkdir()
    np.save(directory / "F.npy", F)
    (directory / "meta.json").write_text('{"material": "stvk", "params": [1]}')
    assert error(directory) == f"{directory / 'meta.json'}: params must be a JSON object {{\"key\": value}}, not list"

    with pytest.raises(FileFormatError, match="format 'xlsx' is unknown"):
        write_arrays(tmp_path / "x.xlsx", {"F": F}, "xlsx")
    with pytest.raises(FileFormatError, match="P: 29 samples, F has 30"):
        write_arrays(tmp_path / "x.csv", {"F": F, "P": np.zeros((29, 3, 3))})


def test_emit_npz_as_written_today(tmp_path: Path) -> None:
    """A file as `verify emit` writes it with numpy.savez (0-d string arrays for the text) reads unchanged."""
    rng = np.random.default_rng(7)
    data = {"F": rng.standard_normal((4, 3, 3)), "psi": rng.standard_normal(4), "P": rng.standard_normal((4, 3, 3)),
            "A": rng.standard_normal((4, 3, 3, 3, 3)), "S": rng.standard_normal((4, 3, 3)),
            "labels": np.array(["identity", "rotation", "uniaxial", "isotropic"]),
            "material": np.array("shape_target"), "params_json": np.array('{"kappa": 0.0, "mu": 1.0}')}
    np.savez(tmp_path / "ref.npz", **data)
    back = read_arrays(tmp_path / "ref.npz")
    assert back["material"] == "shape_target" and json.loads(back["params_json"]) == {"kappa": 0.0, "mu": 1.0}
    for key in ("F", "psi", "P", "A", "S"):
        np.testing.assert_array_equal(back[key], data[key])
    assert list(back["labels"]) == list(data["labels"])


def test_help_names_every_csv_quantity() -> None:
    from model.verify.files import csv_columns, formats_help

    text = formats_help()
    for key, variants in csv_columns().items():
        assert variants[0][0][0] in text, key
