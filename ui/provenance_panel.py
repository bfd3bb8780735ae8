"""The Provenance panel: where the volume on show came from, as :func:`app.provenance.provenance` describes it.
Slices invented by interpolation (and gantry tilt) head the panel in red; every load warning stays listed for as
long as the volume is open; then the series used and those left out with the reason, the DICOM patient, study and
series fields, and the geometry."""

from __future__ import annotations

import html

from qtpy.QtWidgets import QTextBrowser, QWidget

from app.provenance import FIELD_LABELS, provenance

from .panel_layout import panel_layout


def _rows(pairs) -> str:
    return "".join(f"<tr><td><b>{html.escape(str(k))}</b></td><td>{html.escape(str(v))}</td></tr>" for k, v in pairs
                   if v not in (None, "", []))


class ProvenancePanel(QWidget):
    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.browser = QTextBrowser()
        self.browser.setObjectName("provenance")
        self.browser.setOpenLinks(False)
        panel_layout(self, self.browser, stretch=0)
        self.info: dict = {}
        self.browser.setHtml("<i>No volume open.</i>")

    def show_volume(self, volume) -> None:
        self.info = info = provenance(volume)
        parts = []
        for alert in info["alerts"]:
            parts.append(f"<p style='background:#7a1010;color:white;padding:4px'><b>{html.escape(alert)}</b></p>")
        warnings = info["warnings"]
        parts.append(f"<h4>Load warnings ({len(warnings)})</h4>")
        parts.append("<ul>" + "".join(f"<li>{html.escape(w)}</li>" for w in warnings) + "</ul>" if warnings
                     else "<p>None.</p>")
        source = info["source"]
        parts.append("<h4>Source</h4><table>" + _rows([
            ("File", source["file"]), ("Format", source["format"]), ("Series", source["series_description"]),
            ("Series UID", source["series_uid"]), ("Files used", source["files_used"]),
            ("Modality", source["modality"]), ("Values", source["value_units"])]) + "</table>")
        if info["other_series"]:
            parts.append("<h4>Series not used</h4><ul>" + "".join(
                f"<li>{html.escape(s['description'] or 'no description')} ({s['modality'] or '?'}, {s['images']} "
                f"images, {html.escape(s['series_uid'])}): {html.escape(s['reason'])}</li>"
                for s in info["other_series"]) + "</ul>")
        if info["dicom"]:
            parts.append("<h4>Patient, study, series</h4><table>" + _rows(
                (FIELD_LABELS.get(k, k), v) for k, v in info["dicom"].items()) + "</table>")
        g = info["geometry"]
        parts.append("<h4>Geometry</h4><table>" + _rows([
            ("Voxels", " x ".join(map(str, g["dimensions"]))), ("Spacing", " x ".join(f"{s:g}" for s in
                                                                                      g["spacing_mm"]) + " mm"),
            ("Origin (LPS)", ", ".join(f"{o:g}" for o in g["origin_lps_mm"]) + " mm"), ("Axes", g["axes"]),
            ("Direction", "; ".join(" ".join(f"{v:g}" for v in row) for row in g["direction"])),
            ("Bounds (LPS)", ", ".join(f"{b:g}" for b in g["bounds_lps_mm"]) + " mm"),
            ("Values", f"{g['value_range'][0]:g} to {g['value_range'][1]:g} ({g['dtype']})"),
            ("Interpolated slices", g["interpolated_slices"]), ("Gantry tilt", g["gantry_tilt_deg"])]) + "</table>")
        self.browser.setHtml("".join(parts))

    def text(self) -> str:
        return self.browser.toPlainText()
