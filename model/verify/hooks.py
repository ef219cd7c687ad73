"""The one place where tangent layouts and file formats plug into emit and check.

Today: the layout ``ijkl`` (A[n,i,j,k,l] = dP_ij/dF_kl) and .npz files. The other layouts of
shared/design/verification.md (``LAYOUTS``) and the formats .npy directory, CSV and JSON come from
model/verify/layouts.py and model/verify/files.py: wiring them means replacing the bodies of the
five functions below (``to_ijkl``, ``from_ijkl``, ``layout_hints``, ``read_arrays``,
``write_arrays``) and extending ``SUPPORTED_LAYOUTS``/``FORMATS``; emit, check and the command line
call nothing else.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: every tangent layout of verification.md (the --layout choices)
LAYOUTS = ("ijkl", "hessian9-col", "hessian9-row", "voigt-spatial", "abaqus-ddsdde", "voigt-material")
#: the layouts emit and check accept today
SUPPORTED_LAYOUTS = ("ijkl",)
#: the file formats, as the help texts list them: (format, status)
FORMATS = ((".npz", "one archive: F, psi, P, A, fields, labels, material, params_json"),)
PLANNED_FORMATS = (".npy directory (one file per array)", "CSV", "JSON")


def require_layout(layout: str) -> None:
    """ValueError unless ``layout`` is accepted today."""
    if layout not in LAYOUTS:
        raise ValueError(f"--layout {layout!r}: unknown (choose from {', '.join(LAYOUTS)})")
    if layout not in SUPPORTED_LAYOUTS:
        raise ValueError(f"--layout {layout}: not available yet (accepted today: {', '.join(SUPPORTED_LAYOUTS)})")


def to_ijkl(tangent: np.ndarray, layout: str, num_samples: int, **context: np.ndarray) -> np.ndarray:
    """A user's tangent in ``layout`` as A (N,3,3,3,3); ``context`` holds F, P (and the stresses a
    spatial layout needs). ValueError naming the array and both shapes when the size is wrong."""
    require_layout(layout)
    tangent = np.asarray(tangent, dtype=np.float64)
    expected = (num_samples, 3, 3, 3, 3)
    if tangent.size != num_samples * 81 or (tangent.ndim and tangent.shape[0] != num_samples):
        raise ValueError(f"A: shape {tangent.shape} does not match {num_samples} samples of F; expected {expected} "
                         "(layout ijkl: A[n,i,j,k,l] = dP_ij/dF_kl)")
    return tangent.reshape(expected)


def from_ijkl(A: np.ndarray, layout: str, **context: np.ndarray) -> dict[str, np.ndarray]:
    """The reference tangent A (N,3,3,3,3) as emit writes it in ``layout``: {array name: values}."""
    require_layout(layout)
    return {"A": A}


def layout_hints(tangent: np.ndarray, reference: np.ndarray, layout: str, rtol: float) -> list[str]:
    """Hints when a user's tangent (in ijkl) equals the reference up to an index permutation (another
    layout read as ``layout``). Filled in by layouts.hints; none today."""
    return []


def read_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of a user's file by name (.npz today; any file name, the content decides)."""
    with open(path, "rb") as handle:
        try:
            data = np.load(handle, allow_pickle=False)
        except (ValueError, EOFError) as err:
            raise ValueError(f"{path}: not a .npz archive ({err})") from None
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError(f"{path}: a single array, not a .npz archive of named arrays (F, P, A, ...)")
        with data:
            return {k: data[k] for k in data.files}


def write_arrays(path: Path, data: dict[str, np.ndarray]) -> Path:
    """Write ``data`` to exactly ``path`` (np.savez would append .npz to a name without it); returns it."""
    path = Path(path)
    with open(path, "wb") as handle:
        np.savez(handle, **data)
    return path
