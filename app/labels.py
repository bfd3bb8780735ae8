"""Label volumes (atlases, segmentations): detecting them, their colour tables and names, and one mesh per label.

Detection (:func:`is_label_map`)
    An integer-valued, non-negative volume that is not in Hounsfield units, with 2 to :data:`MAX_LABELS` distinct
    values, and piecewise constant: at least half of its non-zero voxels equal their neighbour along i. Grey-value
    images fail the last test by far (the Colin 27 T1 MRI: 5 %; the AAL, Brodmann, JHU and Harvard-Oxford atlases:
    70 to 87 %). ``--labels`` (command line) and File > Open label volume (window) skip the guess.

Colour tables (:func:`read_color_table`), recognised by their lines
    - ITK-SNAP label descriptions: ``IDX R G B A VIS MSH-VIS "LABEL"`` (colours 0-255, alpha 0-1);
    - 3D Slicer colour tables (``.ctbl``/``.txt``) and FreeSurfer's LUT: ``index name R G B A`` (0-255);
    - the AAL text file (``index name code``) and MRIcron's ``index<TAB>name`` lists: names only;
    - MRIcron's binary ``.lut`` (768 bytes: 256 reds, greens, blues): colours only.
    A table next to the volume (``aal.nii.txt``, ``aal.nii.lut``, ``aal.ctbl``, ``aal.label`` ...) is found by
    :func:`find_color_tables`. Labels without a colour get a generated distinct one (golden-angle hues).

Meshes (:func:`export_label_meshes`)
    Each label's voxels become a binary mask (cropped to the label's box plus one voxel, padded by one voxel of
    background so the surface closes at the volume's edge); a surface mode (flying edges by default) extracts its
    0.5 level, and :func:`app.meshing.export_mesh` writes it, one file per label named by label, with one sidecar
    (``labels.json``) listing every mesh with its voxel count, voxel volume and enclosed volume (mm^3).
"""

from __future__ import annotations

import json
import re
import shlex
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from . import __version__
from .io.atomic import atomic_output
from .io.errors import FileExistsRefusal
from .overlays import label_palette
from .volume import Volume

MAX_LABELS = 4096
MIN_CONSTANT_FRACTION = 0.5
TABLE_SUFFIXES = (".txt", ".lut", ".ctbl", ".label", ".csv")


@dataclass
class LabelEntry:
    name: str
    color: tuple[float, float, float] | None = None  # RGB in [0, 1]; None: generated
    alpha: float = 1.0


@dataclass
class LabelTable:
    """Names and colours of labels. ``sources`` lists the files they came from."""

    entries: dict[int, LabelEntry] = field(default_factory=dict)
    sources: list[str] = field(default_factory=list)

    def name(self, label: int) -> str:
        entry = self.entries.get(int(label))
        return entry.name if entry is not None and entry.name else f"label {int(label)}"

    def color(self, label: int) -> tuple[float, float, float]:
        entry = self.entries.get(int(label))
        if entry is not None and entry.color is not None:
            return entry.color
        return tuple(float(c) for c in generated_colors(int(label) + 1)[int(label)])

    def merged(self, other: "LabelTable") -> "LabelTable":
        """Entries of both; ``other``'s names and colours fill what this table lacks."""
        entries = {k: LabelEntry(v.name, v.color, v.alpha) for k, v in self.entries.items()}
        for label, entry in other.entries.items():
            mine = entries.setdefault(label, LabelEntry(""))
            mine.name = mine.name or entry.name
            if mine.color is None:
                mine.color, mine.alpha = entry.color, entry.alpha
        return LabelTable(entries, self.sources + other.sources)

    def rgba(self, count: int, opacity: float = 0.5) -> np.ndarray:
        """A lookup table ``(count, 4)`` float32 for labels 0..count-1: colours, alpha ``opacity`` (label 0 clear)."""
        table = np.zeros((max(count, 1), 4), dtype=np.float32)
        table[:, :3] = generated_colors(len(table))[:, :3]
        for label, entry in self.entries.items():
            if 0 <= label < len(table) and entry.color is not None:
                table[label, :3] = entry.color
        table[:, 3] = opacity
        for label, entry in self.entries.items():
            if 0 <= label < len(table) and entry.alpha <= 0:
                table[label, 3] = 0.0
        table[0] = 0.0
        return table

    def describe(self, labels: Iterable[int] | None = None) -> list[dict[str, Any]]:
        keys = sorted(self.entries) if labels is None else [int(v) for v in labels]
        return [{"label": k, "name": self.name(k), "color": [round(c, 4) for c in self.color(k)]} for k in keys]


def generated_colors(count: int) -> np.ndarray:
    """``count`` distinct colours ``(count, 4)`` float32 (golden-angle hues, bright), label 0 transparent."""
    palette = label_palette(count)
    palette[1:, 3] = 1.0
    return palette


# -- detection ---------------------------------------------------------------------------------------------------
def is_label_map(volume: Volume) -> bool:
    """True when ``volume`` looks like a label map (see the module notes for the rule)."""
    return label_map_reason(volume) is None


def label_map_reason(volume: Volume) -> str | None:
    """Why ``volume`` is not taken for a label map, or None when it is one."""
    if volume.units == "HU" or volume.modality == "CT":
        return "it holds CT values in HU"
    array = volume.array
    step = max(1, int(round((array.size / 4e6) ** (1 / 3))))
    sample = array[::step, ::step, ::step] if step > 1 else array
    if array.dtype.kind == "f":
        if not np.all(np.isfinite(sample)) or not np.all(sample == np.round(sample)):
            return "its values are not whole numbers"
    lo, hi = volume.value_range
    if lo < 0:
        return "it has negative values"
    if hi >= 2**31:
        return "its values are too large for labels"
    values = np.unique(sample)
    if not 2 <= len(values) <= MAX_LABELS:
        return f"it has {len(values)} distinct values (labels: 2 to {MAX_LABELS})"
    if sample.shape[2] < 2:
        return None
    nonzero = sample[:, :, 1:] != 0
    if not nonzero.any():
        return "it is empty"
    constant = float((sample[:, :, 1:] == sample[:, :, :-1])[nonzero].mean())
    if constant < MIN_CONSTANT_FRACTION:
        return f"it is not piecewise constant (only {constant:.0%} of voxels equal their neighbour)"
    return None


def label_values(volume: Volume) -> list[int]:
    """The labels present (non-zero values), ascending."""
    values = np.unique(volume.array)
    return [int(v) for v in values if v != 0]


def as_labels(volume: Volume) -> Volume:
    """The volume with integer storage (labels), refusing what cannot be a label map."""
    array = volume.array
    if array.dtype.kind == "f":
        if not np.all(np.isfinite(array)) or not np.all(array == np.round(array)):
            raise ValueError("a label volume needs whole-number values; this one has fractions")
        array = array.astype(np.int32)
    if array.size and array.min() < 0:
        raise ValueError("a label volume cannot hold negative values")
    return volume.with_array(array, units="", modality=volume.modality if volume.modality != "CT" else "")


# -- colour tables -------------------------------------------------------------------------------------------------
def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def read_color_table(path) -> LabelTable:
    """Names and colours from an ITK-SNAP, 3D Slicer/FreeSurfer, AAL or MRIcron file (see the module notes)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the colour table ({exc.strerror})") from exc
    if path.suffix.lower() == ".lut" and len(data) == 768:
        rgb = np.frombuffer(data, dtype=np.uint8).reshape(3, 256).T / 255.0
        entries = {label: LabelEntry("", tuple(float(c) for c in rgb[label])) for label in range(1, 256)}
        return LabelTable(entries, [str(path)])
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    entries: dict[int, LabelEntry] = {}
    alphas_zero = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        try:
            tokens = shlex.split(line, posix=True) if '"' in line else re.split(r"[\s,;]+", line)
        except ValueError:
            tokens = line.split()
        if not tokens or _number(tokens[0]) is None:
            continue
        label = int(float(tokens[0]))
        numbers = [_number(t) for t in tokens[1:]]
        if '"' in line and len(tokens) >= 8 and all(n is not None for n in numbers[:6]):  # ITK-SNAP
            r, g, b, a = numbers[0], numbers[1], numbers[2], numbers[3]
            entries[label] = LabelEntry(tokens[7], (r / 255, g / 255, b / 255), float(a))
        elif len(tokens) >= 6 and all(n is not None for n in numbers[-4:]) and numbers[0] is None:  # Slicer/FS
            r, g, b, a = numbers[-4:]
            if not all(0 <= c <= 255 for c in (r, g, b, a)):
                raise ValueError(f"{path}, line {number}: colour components must lie in 0..255, got {tokens[-4:]}")
            entries[label] = LabelEntry(" ".join(tokens[1:-4]), (r / 255, g / 255, b / 255), a / 255)
            alphas_zero.append(a == 0)
        elif len(tokens) == 3 and numbers[1] is not None and numbers[0] is None:  # AAL: index name code
            entries[label] = LabelEntry(tokens[1])
        elif len(tokens) >= 2:
            entries[label] = LabelEntry(" ".join(tokens[1:]))
    if not entries:
        raise ValueError(f"{path}: no label lines found; expected an ITK-SNAP, 3D Slicer, FreeSurfer, AAL or MRIcron "
                         "colour table")
    if alphas_zero and all(alphas_zero[1:] or [False]):  # FreeSurfer's column is transparency: 0 means opaque
        for entry in entries.values():
            entry.alpha = 1.0
    return LabelTable(entries, [str(path)])


def find_color_tables(volume_path) -> list[Path]:
    """Colour tables lying next to a label volume: ``NAME.nii.txt``, ``NAME.txt``, ``NAME.lut``, ``NAME.ctbl`` ..."""
    path = Path(volume_path)
    if not path.name:
        return []
    stems = {path.name}
    name = path.name
    for suffix in (".gz", ".nii", ".nrrd", ".nhdr", ".mha", ".mhd", ".vti", ".img", ".hdr"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
            stems.add(name)
    found = []
    for stem in sorted(stems, key=len, reverse=True):
        for suffix in TABLE_SUFFIXES:
            candidate = path.with_name(stem + suffix)
            if candidate.is_file() and candidate not in found:
                found.append(candidate)
    return found


def table_for(volume: Volume, table_path=None) -> LabelTable:
    """The label table of a label volume: ``table_path`` if given, else the tables next to its file (names and
    colours merged), else generated colours with ``label N`` names."""
    if table_path is not None:
        return read_color_table(table_path)
    table = LabelTable()
    for candidate in find_color_tables(volume.metadata.get("source_path", "")):
        try:
            table = table.merged(read_color_table(candidate))
        except ValueError:
            continue  # a text file beside the volume that is no colour table
    return table


# -- meshes --------------------------------------------------------------------------------------------------------
def parse_label_choice(text: str | Sequence[int], present: Sequence[int]) -> list[int]:
    """``all`` or ``1,5,9`` (or a list) -> the labels to mesh; a label not in the volume is a ValueError."""
    if isinstance(text, str):
        if text.strip().lower() == "all":
            return list(present)
        try:
            chosen = [int(part) for part in text.split(",") if part.strip()]
        except ValueError:
            raise ValueError(f"--labels takes 'all' or label numbers separated by commas, got {text!r}") from None
    else:
        chosen = [int(v) for v in text]
    if not chosen:
        raise ValueError("no labels chosen")
    missing = sorted(set(chosen) - set(present))
    if missing:
        shown = ", ".join(map(str, present[:20])) + (" ..." if len(present) > 20 else "")
        raise ValueError(f"label(s) {', '.join(map(str, missing))} do not occur in the volume (labels: {shown})")
    return sorted(set(chosen))


def mesh_file_name(label: int, name: str, suffix: str) -> str:
    """``007_Frontal_Sup_L.stl``: the label number first (sorts), then its name made safe for file systems."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "label"
    return f"{int(label):03d}_{safe[:60]}{suffix}"


def export_label_meshes(volume: Volume, folder, *, labels: str | Sequence[int] = "all", table: LabelTable | None = None,
                        method: str = "flying-edges", suffix: str = ".stl", coordinates: str = "LPS",
                        cleanup=None, options: dict | None = None, overwrite: bool = False,
                        progress=None) -> dict[str, Any]:
    """Write one closed mesh per label into ``folder`` and ``folder/labels.json`` listing them; returns the listing.

    Every file is checked before anything is written: an existing mesh or ``labels.json`` is refused unless
    ``overwrite``.
    """
    from scipy import ndimage

    from .meshing import MESH_SUFFIXES, export_mesh

    suffix = suffix if suffix.startswith(".") else "." + suffix
    if suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"mesh format {suffix!r} is not one of {', '.join(MESH_SUFFIXES)}")
    volume = as_labels(volume)
    present = label_values(volume)
    if not present:
        raise ValueError("the label volume holds no labels (every voxel is 0)")
    chosen = parse_label_choice(labels, present)
    table = table or table_for(volume)
    folder = Path(folder).expanduser()
    listing_path = folder / "labels.json"
    targets = {label: folder / mesh_file_name(label, table.name(label), suffix) for label in chosen}
    if not overwrite:
        for target in [listing_path, *targets.values()]:
            if target.exists():
                raise FileExistsRefusal(target)
    folder.mkdir(parents=True, exist_ok=True)
    array = volume.array
    boxes = ndimage.find_objects(array if array.dtype.kind in "iu" else array.astype(np.int64), max_label=max(chosen))
    voxel_mm3 = float(np.prod(volume.spacing))
    meshes = []
    started = time.perf_counter()
    for number, label in enumerate(chosen):
        box = boxes[label - 1]
        k, j, i = [(max(s.start - 1, 0), min(s.stop + 1, n)) for s, n in zip(box, array.shape)]
        crop = volume.crop(i, j, k)
        mask = crop.with_array((crop.array == label).astype(np.uint8), units="", modality="")
        mask.metadata["source_path"] = volume.metadata.get("source_path", "")

        def part(fraction, number=number):
            if progress is not None:
                progress((number + fraction) / len(chosen))

        export = export_mesh(mask, targets[label], method=method, iso=0.5, options=options, coordinates=coordinates,
                             cleanup=cleanup, close_edges=True, overwrite=overwrite, progress=part, sidecar=False)
        voxels = int(np.count_nonzero(mask.array))
        validity = export.validity or {}
        meshes.append({
            "label": label, "name": table.name(label), "color": [round(c, 4) for c in table.color(label)],
            "file": targets[label].name, "voxels": voxels, "voxel_volume_mm3": voxels * voxel_mm3,
            "mesh_volume_mm3": validity.get("volume_mm3"), "area_mm2": validity.get("area_mm2"),
            "triangles": export.written.get("triangles"), "watertight": validity.get("watertight"),
            "manifold": validity.get("manifold"), "outward_normals": validity.get("outward_normals"),
        })
    listing = {
        "software": f"Voxelscope {__version__}",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "source_file": volume.metadata.get("source_path", ""),
        "colour_tables": table.sources,
        "method": method,
        "iso_value": 0.5,
        "coordinate_system": coordinates.upper(),
        "length_units": "mm",
        "voxel_volume_mm3": voxel_mm3,
        "seconds": round(time.perf_counter() - started, 3),
        "meshes": meshes,
    }
    with atomic_output(listing_path, overwrite=overwrite) as temporary:
        temporary.write_text(json.dumps(listing, indent=2) + "\n")
    if progress is not None:
        progress(1.0)
    return listing
