"""SMPL-family body models read from their own files, and their forward pass, with no chumpy and no smplx package.

In: a model file as users download it (SMPL's Python-2 pickles whose arrays are `chumpy` objects and whose joint
regressor is a `scipy.sparse` matrix; SMPL-X's `.npz` or `.pkl`; the stand-in this project writes, see
`standin.py`). Out: a `BodyModel` of plain numpy arrays, and `forward()`, which poses it in torch (differentiable,
so the fitter optimises through it).

The forward pass follows the SMPL paper (Loper et al. 2015, eqs. 1-4), written here from the model's arrays:
shape blend shapes `v_template + shapedirs · betas`, joints regressed from the shaped mesh, pose blend shapes from
`R(θ_j) − I` of every non-root joint, then linear blend skinning along `kintree_table`'s chain. The same code
serves SMPL (24 joints), SMPL-H and SMPL-X (55 joints; their expression directions follow the shape directions in
`shapedirs` and are left at zero here). It is our own implementation; no SMPL or smplx code is used or needed.

Model files are never bundled or downloaded: the user passes the folder holding their own copies (SMPL's licence).
"""
from __future__ import annotations

import hashlib
import io
import pickle
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["BodyModel", "SmplModelError", "load_body_model", "find_model_file", "forward", "write_smpl_pickle",
           "write_smplx_npz", "rodrigues", "MODEL_FILE_NAMES", "GENDERS", "SMPLX_EXTRA_KEYS"]

GENDERS = ("neutral", "male", "female")

MODEL_FILE_NAMES = {
    # The names the clients load (IntrinsicAvatar, smplx) first, then the names SMPL's and SMPLify's downloads carry.
    "smpl": {
        "neutral": ("SMPL_NEUTRAL.pkl", "basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl",
                    "basicModel_neutral_lbs_10_207_0_v1.0.0.pkl", "basicmodel_neutral_lbs_10_207_0_v1.0.0.pkl"),
        "male": ("SMPL_MALE.pkl", "basicmodel_m_lbs_10_207_0_v1.1.0.pkl", "basicmodel_m_lbs_10_207_0_v1.0.0.pkl",
                 "basicModel_m_lbs_10_207_0_v1.0.0.pkl"),
        "female": ("SMPL_FEMALE.pkl", "basicmodel_f_lbs_10_207_0_v1.1.0.pkl", "basicmodel_f_lbs_10_207_0_v1.0.0.pkl",
                   "basicModel_f_lbs_10_207_0_v1.0.0.pkl"),
    },
    "smplx": {
        "neutral": ("SMPLX_NEUTRAL.npz", "SMPLX_NEUTRAL.pkl"),
        "male": ("SMPLX_MALE.npz", "SMPLX_MALE.pkl"),
        "female": ("SMPLX_FEMALE.npz", "SMPLX_FEMALE.pkl"),
    },
}

JOINT_COUNTS = {"smpl": 24, "smplx": 55}
NAMES = {"smpl": "SMPL", "smplx": "SMPL-X"}
# What SMPL-X files carry beyond the body model (facial landmarks, hand PCA): kept so a stand-in round-trips.
SMPLX_EXTRA_KEYS = ("lmk_faces_idx", "lmk_bary_coords", "dynamic_lmk_faces_idx", "dynamic_lmk_bary_coords",
                    "hands_componentsl", "hands_componentsr", "hands_meanl", "hands_meanr")
# ... and the stand-in's own record (standin.py), so exports can say it is not SMPL.
_KEPT_EXTRAS = ("rh_standin", *SMPLX_EXTRA_KEYS)


class SmplModelError(ValueError):
    """A model file that cannot serve: the message names the file and the fix."""


@dataclass(frozen=True)
class BodyModel:
    """A SMPL-family model as plain arrays (float64 as stored; the forward pass casts).

    v_template (V,3) rest vertices; shapedirs (V,3,S) shape (and for SMPL-X expression) directions; posedirs
    (V,3,9·(J−1)) pose-corrective directions; J_regressor (J,V) dense; weights (V,J) skinning weights; parents (J,)
    with −1 at the root; faces (F,3)."""

    kind: str
    gender: str
    v_template: np.ndarray
    shapedirs: np.ndarray
    posedirs: np.ndarray
    J_regressor: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    faces: np.ndarray
    path: str = ""
    sha256: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def n_vertices(self) -> int:
        return int(self.v_template.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.parents.shape[0])

    @property
    def n_betas(self) -> int:
        """Shape directions only: SMPL-X stores 300 shape + 100 expression (v1.1) or 10 + 10 (v1.0, and the
        stand-in), as smplx reads them; the clients use the first 10."""
        n = int(self.shapedirs.shape[2])
        if self.kind != "smplx":
            return n
        return 300 if n >= 400 else min(n, 10)


# ---------------------------------------------------------------------------------------------------------- reading

class _Opaque:
    """Stands in for a class we refuse to import (chumpy's `Ch`, scipy's sparse matrices): keeps the pickled state."""

    _rh_module = ""
    _rh_name = ""

    def __init__(self, *args, **kwargs):
        self._rh_args = args
        self._rh_state = None

    def __setstate__(self, state):
        self._rh_state = state

    def __reduce__(self):  # pragma: no cover - never re-pickled
        raise TypeError("an opaque stand-in cannot be pickled")


def _opaque_class(module: str, name: str) -> type:
    return type(name, (_Opaque,), {"_rh_module": module, "_rh_name": name})


def _opaque_new(cls, *args):
    return cls.__new__(cls)


_ALLOWED = {
    ("copy_reg", "_reconstructor"), ("copyreg", "_reconstructor"), ("__builtin__", "object"),
    ("builtins", "object"), ("numpy", "ndarray"), ("numpy", "dtype"), ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
    ("numpy", "float64"), ("numpy", "int64"), ("numpy", "uint32"), ("numpy", "int32"),
    ("__builtin__", "set"), ("builtins", "set"), ("__builtin__", "frozenset"), ("builtins", "frozenset"),
    ("collections", "OrderedDict"), ("_codecs", "encode"), ("numpy.core.numeric", "_frombuffer"), ("numpy._core.numeric", "_frombuffer"),
}


class _Unpickler(pickle.Unpickler):
    """Builds numpy arrays and plain containers only; chumpy and scipy.sparse become `_Opaque` records."""

    def find_class(self, module, name):
        if module.split(".")[0] in ("chumpy", "scipy"):
            return _opaque_class(module, name)
        if (module, name) in _ALLOWED:
            if module in ("copy_reg", "copyreg") and name == "_reconstructor":
                return _reconstructor
            import importlib

            target = {"copy_reg": "copyreg", "__builtin__": "builtins"}.get(module, module)
            target = target.replace("numpy.core.", "numpy._core.") if not _has_module(target) else target
            return getattr(importlib.import_module(target), name)
        raise pickle.UnpicklingError(f"refusing to load {module}.{name}")


def _has_module(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def _reconstructor(cls, base, state):
    """copyreg._reconstructor, restricted: opaque records and numpy arrays only."""
    if isinstance(cls, type) and issubclass(cls, _Opaque):
        return cls.__new__(cls)
    import copyreg

    return copyreg._reconstructor(cls, base, state)


def _plain(value, what: str, path: Path):
    """Turn what the unpickler made into numpy: chumpy `Ch` keeps its value in state['x'], sparse matrices theirs
    in data/indices/indptr/_shape (CSC or CSR)."""
    if isinstance(value, _Opaque):
        state = value._rh_state if isinstance(value._rh_state, dict) else {}
        if value._rh_module.startswith("chumpy"):
            if "x" in state:
                return np.asarray(_plain(state["x"], what, path))
            raise SmplModelError(f"{path}: {what} is a chumpy {value._rh_name} with no stored value; "
                                 "re-save the model with plain numpy arrays")
        if value._rh_module.startswith("scipy"):
            shape = state.get("_shape") or state.get("shape")
            kind = value._rh_name[:3]
            if kind in ("csc", "csr") and shape is not None:
                data = np.asarray(state["data"], np.float64)
                indices = np.asarray(state["indices"], np.int64)
                indptr = np.asarray(state["indptr"], np.int64)
                dense = np.zeros(tuple(int(s) for s in shape), np.float64)
                major = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
                if kind == "csc":
                    np.add.at(dense, (indices, major), data)
                else:
                    np.add.at(dense, (major, indices), data)
                return dense
            raise SmplModelError(f"{path}: {what} is a scipy {value._rh_name}, which this reader does not know; "
                                 "re-save it as a dense numpy array")
    return value


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _read_arrays(path: Path) -> dict:
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise SmplModelError(f"{path}: cannot read the model file ({e.strerror or e}); check the path and its "
                             "permissions") from None
    if raw[:2] == b"PK":  # .npz (SMPL-X's usual download)
        try:
            with np.load(io.BytesIO(raw), allow_pickle=False) as z:
                return {k: v for k in z.files if (v := _npz_array(z, k)) is not None}
        except (ValueError, zipfile.BadZipFile, OSError) as e:
            raise SmplModelError(f"{path}: not a readable .npz model ({e}); download the model file again") from None
    try:
        data = _Unpickler(io.BytesIO(raw), encoding="latin1").load()
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, TypeError, ValueError, IndexError) as e:
        raise SmplModelError(f"{path}: not a readable SMPL model pickle ({e}); download the model file again "
                             "or pass the folder holding SMPL_NEUTRAL.pkl") from None
    if not isinstance(data, dict):
        raise SmplModelError(f"{path}: the pickle holds a {type(data).__name__}, not a SMPL model dictionary")
    return {k: _plain(v, k, path) for k, v in data.items()}


def _npz_array(z, key: str):
    """One array of an .npz, or None for a pickled object array (SMPL-X's downloads carry `joint2num` and
    `part2num` dictionaries that way): the model needs none of them, and unpickling is what the reader refuses."""
    try:
        return z[key]
    except ValueError as e:
        if "allow_pickle" in str(e):
            return None
        raise


def load_body_model(path: str | Path, kind: str = "smpl", gender: str = "neutral") -> BodyModel:
    """Read a SMPL (kind 'smpl', 24 joints, 6890 vertices) or SMPL-X (kind 'smplx', 55 joints, 10475 vertices)
    model file and check its arrays agree with each other."""
    path = Path(path)
    if kind not in JOINT_COUNTS:
        raise SmplModelError(f"unknown body model kind {kind!r}; known: {', '.join(JOINT_COUNTS)}")
    arrays = _read_arrays(path)
    need = ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f")
    missing = [k for k in need if k not in arrays]
    if missing:
        raise SmplModelError(f"{path}: missing {', '.join(missing)}; this is not a {NAMES[kind]} model file")

    def arr(k, dtype=np.float64):
        try:
            return np.ascontiguousarray(np.asarray(arrays[k], dtype=dtype))
        except (TypeError, ValueError):
            raise SmplModelError(f"{path}: {k} is not a numeric array; download the model file again") from None

    v_template, shapedirs, posedirs = arr("v_template"), arr("shapedirs"), arr("posedirs")
    J_regressor, weights = arr("J_regressor"), arr("weights")
    kintree = arr("kintree_table", np.int64)
    faces = arr("f", np.int64)
    n_joints = JOINT_COUNTS[kind]
    V = v_template.shape[0] if v_template.ndim == 2 else -1
    checks = [
        (v_template.ndim == 2 and v_template.shape[1] == 3, "v_template must be (V, 3)"),
        (shapedirs.ndim == 3 and shapedirs.shape[:2] == (V, 3), "shapedirs must be (V, 3, S)"),
        (posedirs.ndim == 3 and posedirs.shape[:2] == (V, 3) and posedirs.shape[2] == 9 * (n_joints - 1),
         f"posedirs must be (V, 3, {9 * (n_joints - 1)})"),
        (J_regressor.shape == (n_joints, V), f"J_regressor must be ({n_joints}, V)"),
        (weights.shape == (V, n_joints), f"weights must be (V, {n_joints})"),
        (kintree.ndim == 2 and kintree.shape == (2, n_joints), f"kintree_table must be (2, {n_joints})"),
        (faces.ndim == 2 and faces.shape[1] == 3 and faces.size and 0 <= faces.min() and faces.max() < V,
         "f must be (F, 3) vertex indices"),
    ]
    for ok, what in checks:
        if not ok:
            raise SmplModelError(f"{path}: {what} for a {NAMES[kind]} model with {n_joints} joints; is this the "
                                 f"right file (a {NAMES[kind]} model, not another topology)?")
    parents = kintree[0].copy()
    parents[0] = -1
    if np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, n_joints)):
        raise SmplModelError(f"{path}: kintree_table's parents are not ordered root-first; not a {NAMES[kind]} model")
    return BodyModel(kind=kind, gender=gender, v_template=v_template, shapedirs=shapedirs, posedirs=posedirs,
                     J_regressor=J_regressor, weights=weights, parents=parents, faces=faces, path=str(path),
                     sha256=_sha256(path), extra={k: _extra(k, arrays[k]) for k in _KEPT_EXTRAS if k in arrays})


def _extra(key: str, value):
    """The stand-in's record comes back from a .npz as a JSON string (npz holds arrays only, read without pickle)."""
    if key == "rh_standin" and isinstance(value, np.ndarray) and value.dtype.kind == "U" and value.ndim == 0:
        import json

        rec = json.loads(str(value))
        if "anny_vertex_ids" in rec:
            rec["anny_vertex_ids"] = np.asarray(rec["anny_vertex_ids"], np.int64)
        return rec
    return value


def find_model_file(folder: str | Path, kind: str = "smpl", gender: str = "neutral") -> Path:
    """The file of `gender` in the user's model folder, under any of the usual names."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SmplModelError(f"{folder}: no such folder; pass the folder holding your own "
                             f"{MODEL_FILE_NAMES[kind][gender][0]} (or write a stand-in with rh-export "
                             f"--write-test-{kind})")
    for sub in (folder, folder / kind):
        for name in MODEL_FILE_NAMES[kind][gender]:
            if (sub / name).is_file():
                return sub / name
    raise SmplModelError(f"{folder}: no {NAMES[kind]} {gender} model file (looked for "
                         f"{', '.join(MODEL_FILE_NAMES[kind][gender])}); put your own copy there, or write a "
                         f"stand-in with rh-export --write-test-{kind} DIR")


def write_smpl_pickle(path: str | Path, model: BodyModel) -> None:
    """Write `model` in SMPL's pickle layout with plain numpy arrays (protocol 2, which Python 2 and the clients'
    `pickle.load(..., encoding='latin1')` read; no chumpy needed to load it)."""
    from rh_common.imageio import atomic_path

    data = {
        "v_template": model.v_template, "shapedirs": model.shapedirs, "posedirs": model.posedirs,
        "J_regressor": model.J_regressor, "weights": model.weights,
        "kintree_table": np.stack([np.where(model.parents < 0, 4294967295, model.parents),
                                   np.arange(model.n_joints)]).astype(np.int64),
        "f": model.faces.astype(np.uint32), "bs_type": "lrotmin", "bs_style": "lbs",
        "J": model.J_regressor @ model.v_template,
    }
    data.update(model.extra)
    with atomic_path(Path(path)) as tmp:
        with open(tmp, "wb") as fh:
            pickle.dump(data, fh, protocol=2)


def write_smplx_npz(path: str | Path, model: BodyModel) -> None:
    """Write `model` as a SMPL-X .npz (the keys smplx's loader and `load_body_model` read, plus the model's
    SMPL-X extras); compressed, since the stand-in's zero pose correctives are most of its bytes, and bitwise
    reproducible. The stand-in's record is stored as a JSON string so the file loads with allow_pickle=False."""
    import json

    from rh_common.imageio import atomic_path

    data = {
        "v_template": model.v_template, "shapedirs": model.shapedirs, "posedirs": model.posedirs,
        "J_regressor": model.J_regressor, "weights": model.weights,
        "kintree_table": np.stack([np.where(model.parents < 0, 4294967295, model.parents),
                                   np.arange(model.n_joints)]).astype(np.int64),
        "f": model.faces.astype(np.uint32), "J": model.J_regressor @ model.v_template,
    }
    for k, v in model.extra.items():
        if k == "rh_standin":
            v = np.array(json.dumps(v, sort_keys=True, default=lambda o: np.asarray(o).tolist()))
        data[k] = v
    import zipfile

    # np.savez_compressed's layout (one deflated NAME.npy per array), written here so every entry carries one fixed
    # timestamp: np.savez stamps the current time, and the same model must give the same bytes (its sha256 keys
    # the fit caches and is recorded in every export).
    with atomic_path(Path(path)) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for k, v in data.items():
                info = zipfile.ZipInfo(f"{k}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                with zf.open(info, "w", force_zip64=True) as fh:
                    np.lib.format.write_array(fh, np.asanyarray(v), allow_pickle=False)


# ---------------------------------------------------------------------------------------------------------- forward

def rodrigues(aa):
    """(…,3) axis-angle → (…,3,3) rotation matrices, in torch; exact at zero angle (the series' first terms)."""
    import torch

    theta2 = (aa * aa).sum(-1, keepdim=True)
    theta = torch.sqrt(theta2 + 1e-30)
    small = theta2 < 1e-12
    # sin(θ)/θ and (1 − cos θ)/θ², with their Taylor series near zero so gradients stay finite there.
    a = torch.where(small, 1 - theta2 / 6, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24, (1 - torch.cos(theta)) / torch.where(small, torch.ones_like(theta2),
                                                                                   theta2))
    x, y, z = aa.unbind(-1)
    zero = torch.zeros_like(x)
    K = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], -1).reshape(*aa.shape[:-1], 3, 3)
    eye = torch.eye(3, dtype=aa.dtype, device=aa.device).expand_as(K)
    return eye + a[..., None] * K + b[..., None] * (K @ K)


def forward(model: BodyModel, betas, body_pose, global_orient, transl=None, tensors: dict | None = None):
    """Pose the model. betas (B,≤S), body_pose (B,3·(J−1)) parent-relative axis-angle of joints 1…J−1,
    global_orient (B,3), transl (B,3) or None. Returns (vertices (B,V,3), joints (B,J,3)) in the model's units
    (metres), the root joint rotating about itself: `vertices = R·(rest − J0) + J0 + …` as SMPL defines it.
    `tensors`: the model's arrays already as torch tensors (`model_tensors`), to skip the conversion per call."""
    import torch

    t = tensors if tensors is not None else model_tensors(model, dtype=betas.dtype)
    B = betas.shape[0]
    n_b = betas.shape[1]
    V = t["v_template"].shape[0]
    # Matrix products on flat views (no permuted copies of the (V,3,S) and (V,3,P) arrays; einsum made those).
    S = t["shapedirs"].reshape(V * 3, t["shapedirs"].shape[2])[:, :n_b]
    v_shaped = t["v_template"][None] + (betas @ S.T).reshape(B, V, 3)
    # Joints from the regressed template and shape directions: J_regressor · (T + S·β) = J_regressor·T +
    # (J_regressor·S)·β, which holds for any vertex subset in `tensors` (model_tensors(vertex_ids=...)).
    J = t["J_template"][None] + torch.einsum("bs,jcs->bjc", betas, t["J_shapedirs"][..., :n_b])
    full = torch.cat([global_orient.reshape(B, 1, 3), body_pose.reshape(B, -1, 3)], 1)
    R = rodrigues(full)                                                         # (B,J,3,3)
    eye = torch.eye(3, dtype=R.dtype, device=R.device)
    pose_feature = (R[:, 1:] - eye).reshape(B, -1)
    if t["posedirs"] is None:  # all zero (the stand-in): the same result without the largest product
        v_posed = v_shaped
    else:
        P = t["posedirs"].reshape(V * 3, t["posedirs"].shape[2])
        v_posed = v_shaped + (pose_feature @ P.T).reshape(B, V, 3)
    parents = model.parents
    rel = J.clone()
    rel[:, 1:] = J[:, 1:] - J[:, parents[1:]]
    local = torch.cat([torch.cat([R, rel[..., None]], -1),
                       torch.tensor([0, 0, 0, 1], dtype=R.dtype, device=R.device).expand(B, R.shape[1], 1, 4)], -2)
    chain = [local[:, 0]]
    for j in range(1, R.shape[1]):
        chain.append(chain[parents[j]] @ local[:, j])
    G = torch.stack(chain, 1)                                                  # (B,J,4,4) world transforms
    posed_joints = G[:, :, :3, 3]
    # Remove the rest joint location so each transform acts on rest-pose coordinates.
    offset = posed_joints - torch.einsum("bjik,bjk->bji", G[:, :, :3, :3], J)
    n_j = R.shape[1]
    T_rot = (t["weights"] @ G[:, :, :3, :3].reshape(B, n_j, 9)).reshape(B, V, 3, 3)
    T_off = t["weights"] @ offset
    verts = torch.einsum("bvik,bvk->bvi", T_rot, v_posed) + T_off
    if transl is not None:
        verts = verts + transl[:, None]
        posed_joints = posed_joints + transl[:, None]
    return verts, posed_joints


def model_tensors(model: BodyModel, dtype=None, vertex_ids=None) -> dict:
    """The model's arrays as torch tensors (float64 unless `dtype`), for repeated `forward` calls. With
    `vertex_ids`, `forward` poses only those vertices (in that order); the joints still come from the whole mesh."""
    import torch

    dtype = dtype or torch.float64
    idx = slice(None) if vertex_ids is None else np.asarray(vertex_ids, np.int64)
    t = {k: torch.as_tensor(np.ascontiguousarray(getattr(model, k)[idx]), dtype=dtype)
         for k in ("v_template", "shapedirs", "weights")}
    t["posedirs"] = (torch.as_tensor(np.ascontiguousarray(model.posedirs[idx]), dtype=dtype)
                     if model.posedirs.any() else None)
    t["J_template"] = torch.as_tensor(model.J_regressor @ model.v_template, dtype=dtype)
    t["J_shapedirs"] = torch.as_tensor(np.einsum("jv,vcs->jcs", model.J_regressor, model.shapedirs), dtype=dtype)
    return t
