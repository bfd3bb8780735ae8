"""Label volumes: detection, every colour-table format, and ``voxelscope mesh LABELS --labels ... -o DIR --json``
writing one closed mesh per label whose volume matches the voxel count (shapes made in code; the AAL atlas of
Debian's mricron-data when it is installed)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from app.io import save_volume
from app.labels import (
    LabelTable,
    find_color_tables,
    is_label_map,
    label_map_reason,
    mesh_file_name,
    parse_label_choice,
    read_color_table,
    table_for,
)
from app.samples import sample_path
from app.volume import Volume

from .test_cli import voxelscope

AAL = Path("/usr/share/mricron/templates/aal.nii.gz")


def label_volume() -> Volume:
    """Three labels with different shapes; label 9 touches the volume's edge (its mesh must still close)."""
    z, y, x = np.mgrid[0:48, 0:55, 0:64]
    labels = np.zeros((48, 55, 64), np.uint8)
    labels[(x - 20) ** 2 + (y - 28) ** 2 + (z - 24) ** 2 <= 12 ** 2] = 1
    labels[((x - 47) / 10.0) ** 2 + ((y - 30) / 16.0) ** 2 + ((z - 22) / 13.0) ** 2 <= 1] = 5
    labels[30:48, 3:20, 0:25] = 9
    return Volume(labels, spacing=(0.9, 1.0, 1.3), origin=(-30.0, -20.0, 10.0))


def test_detection_tells_labels_from_grey_values():
    assert is_label_map(label_volume())
    mri = Volume(np.asarray(__import__("nibabel").load(sample_path("mri")).dataobj))
    assert "not piecewise constant" in label_map_reason(mri)
    ct = Volume(label_volume().array.astype(np.int16), units="HU", modality="CT")
    assert "HU" in label_map_reason(ct)
    noisy = Volume(np.random.default_rng(0).normal(size=(10, 10, 10)).astype(np.float32))
    assert "whole numbers" in label_map_reason(noisy)
    assert "distinct values" in label_map_reason(Volume(np.ones((5, 5, 5), np.uint8)))


@pytest.mark.skipif(not AAL.exists(), reason="the AAL atlas (Debian package mricron-data) is not installed")
def test_the_aal_atlas_is_detected_with_its_names_and_colours():
    from app.io import load_volume

    atlas = load_volume(AAL)
    assert is_label_map(atlas)
    table = table_for(atlas)
    assert table.name(1) == "Precentral_L" and table.name(116) == "Vermis_10"
    assert table.entries[1].color is not None  # from aal.nii.lut


def test_colour_table_formats(tmp_path):
    itk = tmp_path / "seg.label"
    itk.write_text('################################################\n# ITK-SnAP Label Description File\n'
                   '    0     0    0    0        0  0  0    "Clear Label"\n'
                   '    1   255    0    0        1  1  1    "Left ventricle"\n'
                   '    2     0  128  255      0.5  1  1    "Tumour core"\n')
    table = read_color_table(itk)
    assert table.name(1) == "Left ventricle" and table.color(2) == pytest.approx((0, 128 / 255, 1))
    assert table.entries[2].alpha == 0.5
    slicer = tmp_path / "colors.ctbl"
    slicer.write_text("# Color table file\n# 3 values\n0 Background 0 0 0 0\n1 liver tissue 221 130 101 255\n"
                      "7 spleen 157 108 162 255\n")
    table = read_color_table(slicer)
    assert table.name(1) == "liver tissue" and table.color(7) == pytest.approx((157 / 255, 108 / 255, 162 / 255))
    freesurfer = tmp_path / "FreeSurferColorLUT.txt"
    freesurfer.write_text("#No. Label Name:   R   G   B   A\n0   Unknown   0   0   0   0\n"
                          "2   Left-Cerebral-White-Matter   245 245 245 0\n17  Left-Hippocampus  220 216 20  0\n")
    table = read_color_table(freesurfer)
    assert table.name(17) == "Left-Hippocampus" and table.entries[17].alpha == 1.0  # FreeSurfer's 0 = opaque
    aal = tmp_path / "atlas.nii.txt"
    aal.write_text("1 Precentral_L 2001\n2 Precentral_R 2002\n")
    table = read_color_table(aal)
    assert table.name(2) == "Precentral_R" and table.entries[2].color is None
    lut = tmp_path / "atlas.nii.lut"
    lut.write_bytes(bytes(range(256)) + bytes(256) + bytes([255] * 256))
    assert read_color_table(lut).color(3) == pytest.approx((3 / 255, 0, 1))
    assert [p.name for p in find_color_tables(tmp_path / "atlas.nii.gz")] == ["atlas.nii.txt", "atlas.nii.lut"]
    merged = table_for(Volume(np.zeros((2, 2, 2)), metadata={"source_path": str(tmp_path / "atlas.nii.gz")}))
    assert merged.name(1) == "Precentral_L" and merged.color(1) == pytest.approx((1 / 255, 0, 1))
    empty = tmp_path / "notes.txt"
    empty.write_text("no labels here\n")
    with pytest.raises(ValueError, match="no label lines found"):
        read_color_table(empty)


def test_label_choice_and_names():
    assert parse_label_choice("all", [1, 5, 9]) == [1, 5, 9]
    assert parse_label_choice("9,1", [1, 5, 9]) == [1, 9]
    with pytest.raises(ValueError, match="do not occur"):
        parse_label_choice("2", [1, 5, 9])
    with pytest.raises(ValueError, match="'all' or label numbers"):
        parse_label_choice("liver", [1])
    assert mesh_file_name(7, "Frontal Sup/L", ".stl") == "007_Frontal_Sup_L.stl"
    rgba = LabelTable().rgba(4, 0.4)
    assert rgba[0, 3] == 0 and np.all(rgba[1:, 3] == pytest.approx(0.4)) and len({tuple(c) for c in rgba[1:, :3]}) == 3


def test_mesh_command_writes_one_closed_mesh_per_label(tmp_path):
    volume = label_volume()
    path = save_volume(volume, tmp_path / "labels.nii.gz")
    (tmp_path / "labels.nii.txt").write_text("1 Ball 11\n5 Ellipsoid 15\n9 Block 19\n")
    out = tmp_path / "meshes"
    listing = json.loads(voxelscope("mesh", path, "--labels", "all", "-o", out, "--json").stdout)
    assert [m["label"] for m in listing["meshes"]] == [1, 5, 9]
    assert sorted(p.name for p in out.iterdir()) == ["001_Ball.stl", "005_Ellipsoid.stl", "009_Block.stl",
                                                    "labels.json"]
    assert json.loads((out / "labels.json").read_text())["meshes"] == listing["meshes"]
    voxel = 0.9 * 1.0 * 1.3
    for mesh in listing["meshes"]:
        count = int((volume.array == mesh["label"]).sum())
        assert mesh["voxels"] == count and mesh["voxel_volume_mm3"] == pytest.approx(count * voxel)
        assert mesh["watertight"] and mesh["outward_normals"], mesh
        assert abs(mesh["mesh_volume_mm3"] / (count * voxel) - 1) < 0.02, mesh
    # The files are real closed meshes as written (read back independently of the listing).
    from app.io.meshes import describe_mesh, load_mesh

    described = describe_mesh(load_mesh(out / "009_Block.stl"))
    assert described["closed"] and described["orientation"] == "outward" and described["volume_mm3"] == pytest.approx(
        listing["meshes"][2]["mesh_volume_mm3"], rel=1e-3)
    # Some labels only; existing files are refused without --force.
    some = voxelscope("mesh", path, "--labels", "1,9", "-o", tmp_path / "two", "--json")
    assert [m["label"] for m in json.loads(some.stdout)["meshes"]] == [1, 9]
    again = voxelscope("mesh", path, "--labels", "all", "-o", out, check=False)
    assert again.returncode != 0 and "already exists" in again.stderr and "Traceback" not in again.stderr
    missing = voxelscope("mesh", path, "--labels", "3", "-o", tmp_path / "x", check=False)
    assert "label(s) 3 do not occur" in missing.stderr


def test_mesh_command_applies_every_clean_up_flag_to_each_label(tmp_path):
    """--largest (and the other clean-up flags) reach one-mesh-per-label exports as they reach a single surface."""
    from app.io.meshes import describe_mesh, load_mesh

    volume = label_volume()
    volume.array[2:6, 2:6, 40:44] = 1  # a loose fragment of label 1, far from its ball
    path = save_volume(volume, tmp_path / "labels.nii.gz")
    whole, largest = tmp_path / "whole", tmp_path / "largest"
    for folder, flags in ((whole, ()), (largest, ("--largest",))):
        listing = json.loads(voxelscope("mesh", path, "--labels", "1", "-o", folder, "--json", *flags).stdout)
        file = folder / listing["meshes"][0]["file"]
        assert describe_mesh(load_mesh(file))["components"] == (1 if flags else 2), flags
    refused = voxelscope("mesh", path, "--labels", "1", "-o", tmp_path / "bad", "--decimate", "1.5", check=False)
    assert refused.returncode != 0 and "[0, 1)" in refused.stderr and "Traceback" not in refused.stderr
