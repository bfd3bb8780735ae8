"""Where a volume came from, for the window's Provenance panel and for scripts: every load warning (kept, never
timed out), slices invented by interpolation (first, and flagged), the series used and those left out with the
reason, the DICOM patient/study/series fields the reader kept, and the geometry. Also which series of a DICOM
folder can be opened at all (the series chooser greys out the others and says why).
"""

from __future__ import annotations

from typing import Any

#: Labels of the DICOM fields (``volume.metadata["dicom"]``, see :data:`app.io.dicom.headers.STUDY_KEYWORDS`).
FIELD_LABELS = {
    "PatientName": "Patient name", "PatientID": "Patient ID", "PatientBirthDate": "Birth date", "PatientSex": "Sex",
    "PatientAge": "Age", "StudyDate": "Study date", "StudyTime": "Study time", "StudyDescription": "Study",
    "StudyInstanceUID": "Study UID", "AccessionNumber": "Accession number", "SeriesNumber": "Series number",
    "SeriesDescription": "Series", "SeriesDate": "Series date", "Modality": "Modality",
    "BodyPartExamined": "Body part", "ProtocolName": "Protocol", "Manufacturer": "Manufacturer",
    "ManufacturerModelName": "Model", "InstitutionName": "Institution", "SliceThickness": "Slice thickness (mm)",
    "KVP": "kVp", "ConvolutionKernel": "Kernel", "MagneticFieldStrength": "Field strength (T)",
    "RepetitionTime": "TR (ms)", "EchoTime": "TE (ms)",
}


def is_interpolation_warning(text: str) -> bool:
    """True for the reader's warning that slices were filled in by interpolation."""
    return "invented by interpolation" in text


def provenance(volume) -> dict[str, Any]:
    """Sections of the provenance panel, JSON-ready.

    ``alerts``: what must not be missed (slices invented by interpolation); ``warnings``: every load warning, in
    the reader's order; ``source``: file, format, series used; ``other_series``: those not used, with reasons;
    ``dicom``: patient/study/series fields; ``geometry``: dimensions, spacing, origin, direction, bounds.
    """
    metadata = volume.metadata
    warnings = [str(w) for w in metadata.get("warnings", [])]
    alerts = []
    invented = int(metadata.get("interpolated_slices", 0) or 0)
    if invented:
        alerts.append(f"{invented} slice(s) of this volume were not in the data: they were invented by linear "
                      "interpolation between their neighbours. Do not measure or diagnose on them.")
    alerts.extend(w for w in warnings if "gantry tilt" in w)
    source = {
        "file": str(metadata.get("source_path", "")),
        "format": str(metadata.get("source_format", "")),
        "series_uid": str(metadata.get("series_uid", "")),
        "series_description": str(metadata.get("series_description", "")),
        "files_used": metadata.get("files_used"),
        "modality": volume.modality or "unknown",
        "value_units": volume.units_label,
    }
    others = [{"series_uid": s.get("series_uid", ""), "description": s.get("description", ""),
               "modality": s.get("modality", ""), "images": s.get("slices"), "reason": s.get("reason", "")}
              for s in metadata.get("other_series", [])]
    lo, hi = volume.value_range
    geometry = {
        "dimensions": list(volume.dimensions),
        "spacing_mm": [round(s, 6) for s in volume.spacing],
        "origin_lps_mm": [round(o, 4) for o in volume.origin],
        "direction": [[round(float(v), 6) + 0.0 for v in row] for row in volume.direction],
        "axes": "/".join(volume.axis_labels()),
        "bounds_lps_mm": [round(b, 3) for b in volume.world_bounds],
        "value_range": [lo, hi],
        "dtype": str(volume.array.dtype),
        "interpolated_slices": invented,
        "gantry_tilt_deg": metadata.get("gantry_tilt_deg"),
    }
    return {"alerts": alerts, "warnings": warnings, "source": source, "other_series": others,
            "dicom": dict(metadata.get("dicom", {})), "geometry": geometry}


def series_choices(series: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The series of a folder (``app.io.list_series``) with ``loadable`` and ``reason``: a single image (a
    localizer, a screenshot, a dose report) cannot form a volume; neither can an image-less object."""
    choices = []
    for entry in series:
        slices, volumes = int(entry.get("slices", 0)), int(entry.get("volumes", 1) or 1)
        rows, columns = int(entry.get("rows", 0)), int(entry.get("columns", 0))
        reason = ""
        if rows <= 0 or columns <= 0:
            reason = "no image data"
        elif slices < 2:
            reason = "a single image (a localizer or a snapshot): a volume needs at least two slices"
        elif volumes > 1 and slices // volumes < 2:
            reason = f"{volumes} volumes of one image each: none forms a volume"
        choices.append({**entry, "loadable": not reason, "reason": reason})
    return choices

