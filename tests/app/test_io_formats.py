"""NIfTI, Analyze, MINC, NRRD, MetaImage, VTK and raw readers: real files and geometry-keeping round trips."""

from __future__ import annotations

import gzip
import os

import nibabel
import numpy as np
import pytest
from nibabel.testing import data_path

from app.io import (
    CorruptFileError,
    FileExistsRefusal,
    RawLayout,
    UnsupportedFormatError,
    VolumeReadError,
    VolumeWriteError,
    load_volume,
    save_volume,
)
from app.samples import sample_path
from app.volume import Volume

from .dicom_helpers import small_ct, tilted_direction


@pytest.fixture
def oblique_ct():
    volume = small_ct()
    volume.direction = tilted_direction(-17.0)
    return volume


@pytest.mark.parametrize("suffix", [".nii", ".nii.gz", ".nrrd", ".mha", ".mhd", ".vti"])
def test_round_trip_keeps_geometry_values_and_modality(tmp_path, oblique_ct, suffix):
    path = save_volume(oblique_ct, tmp_path / f"volume{suffix}")
    loaded = load_volume(path)
    assert loaded.dimensions == oblique_ct.dimensions
    assert np.allclose(loaded.spacing, oblique_ct.spacing, rtol=1e-6)
    assert np.allclose(loaded.origin, oblique_ct.origin, atol=1e-4)
    assert np.allclose(loaded.direction, oblique_ct.direction, atol=1e-6)
    np.testing.assert_array_equal(loaded.array, oblique_ct.array)
    assert (loaded.modality, loaded.units) == ("CT", "HU")


def test_nifti_is_ras_on_disk(tmp_path):
    volume = small_ct()
    path = save_volume(volume, tmp_path / "v.nii.gz")
    affine = nibabel.load(path).affine
    # LPS origin (x, y, z) is RAS (-x, -y, z).
    assert np.allclose(affine[:3, 3], [-volume.origin[0], -volume.origin[1], volume.origin[2]])


def test_real_nibabel_files():
    anatomical = load_volume(os.path.join(data_path, "anatomical.nii"))
    image = nibabel.load(os.path.join(data_path, "anatomical.nii"))
    assert anatomical.dimensions == image.shape[:3]
    # The same voxel lands at the same patient position (RAS -> LPS), whatever index flips the reader made.
    ijk = np.array([3, 7, 11])
    ras = image.affine @ np.append(ijk, 1)
    lps = np.array([-ras[0], -ras[1], ras[2]])
    index = np.rint(anatomical.world_to_index(lps)).astype(int)
    assert anatomical.array[index[2], index[1], index[0]] == np.asarray(image.dataobj)[tuple(ijk)]
    assert np.linalg.det(anatomical.direction) > 0  # stored left-handed, loaded right-handed

    four_d = load_volume(os.path.join(data_path, "example4d.nii.gz"))
    assert four_d.dimensions == (128, 96, 24)
    assert any("4D" in w for w in four_d.metadata["warnings"])

    minc = load_volume(os.path.join(data_path, "tiny.mnc"))
    assert minc.metadata["source_format"] == "MINC" and minc.dimensions[0] * minc.dimensions[1] * minc.dimensions[2] == 4000


def test_colin27_sample_geometry():
    volume = load_volume(sample_path("mri"))
    assert volume.dimensions == (181, 217, 181)
    assert volume.spacing == (1.0, 1.0, 1.0)
    assert volume.array.dtype == np.uint8
    # MNI space: the anterior commissure is near the origin, the brain spans about -90..90 mm left-right.
    bounds = volume.world_bounds
    assert bounds[0] == pytest.approx(-90, abs=1.5) and bounds[1] == pytest.approx(90, abs=1.5)
    assert volume.axis_labels() in (["R", "A", "S"], ["L", "P", "S"])


def test_analyze_pair(tmp_path):
    data = np.arange(6 * 5 * 4, dtype=np.int16).reshape(6, 5, 4)
    image = nibabel.AnalyzeImage(data, np.diag([2.0, 3.0, 4.0, 1.0]))
    nibabel.save(image, tmp_path / "scan.img")
    volume = load_volume(tmp_path / "scan.hdr")
    assert volume.metadata["source_format"] == "Analyze"
    assert volume.dimensions == (6, 5, 4) and volume.spacing == pytest.approx((2.0, 3.0, 4.0))
    (tmp_path / "scan.img").unlink()
    with pytest.raises(VolumeReadError, match="scan.img: the image data file named by scan.hdr is missing"):
        load_volume(tmp_path / "scan.hdr")


def test_nrrd_spaces_and_detached_header(tmp_path):
    values = np.arange(4 * 5 * 6, dtype=np.int16).reshape(6, 5, 4)
    payload = gzip.compress(values.tobytes())
    header = (
        "NRRD0004\ntype: short\ndimension: 3\nspace: right-anterior-superior\nsizes: 4 5 6\n"
        "space directions: (0.5,0,0) (0,0.7,0) (0,0,2)\nkinds: domain domain domain\nendian: little\n"
        "encoding: gzip\nspace origin: (10,20,30)\n\n"
    )
    (tmp_path / "ras.nrrd").write_bytes(header.encode() + payload)
    volume = load_volume(tmp_path / "ras.nrrd")
    np.testing.assert_array_equal(volume.array, values)
    assert np.allclose(volume.origin, (-10, -20, 30))
    assert np.allclose(volume.index_to_world((1, 1, 1)), (-10.5, -20.7, 32))

    detached = header.replace("encoding: gzip\n", "encoding: raw\ndata file: ras.raw\n")
    (tmp_path / "ras.nhdr").write_text(detached)
    (tmp_path / "ras.raw").write_bytes(values.tobytes())
    np.testing.assert_array_equal(load_volume(tmp_path / "ras.nhdr").array, values)
    (tmp_path / "ras.raw").unlink()
    with pytest.raises(VolumeReadError, match="the data file named by ras.nhdr cannot be read"):
        load_volume(tmp_path / "ras.nhdr")


def test_truncated_files_are_reported(tmp_path):
    volume = small_ct()
    for suffix in (".nrrd", ".nii.gz", ".mha"):
        path = save_volume(volume, tmp_path / f"v{suffix}")
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        with pytest.raises(CorruptFileError, match=rf"v{suffix.replace('.', '[.]')}: .*(truncated|damaged|could not be read)"):
            load_volume(path)


def test_raw_with_explicit_layout(tmp_path):
    values = np.random.default_rng(1).integers(-500, 500, size=(7, 6, 5)).astype(">i2")
    path = tmp_path / "scan.raw"
    path.write_bytes(b"HEADER!!" + values.tobytes())
    layout = RawLayout((5, 6, 7), "int16", (0.5, 0.5, 1.0), byte_order="big", header_bytes=8)
    volume = load_volume(path, raw=layout)
    np.testing.assert_array_equal(volume.array, values.astype(np.int16))
    assert volume.spacing == (0.5, 0.5, 1.0)
    with pytest.raises(CorruptFileError, match="need 512"):
        load_volume(path, raw=RawLayout((6, 6, 7), "int16", byte_order="big", header_bytes=8))
    with pytest.raises(ValueError, match="unknown raw data type 'int17'"):
        load_volume(path, raw=RawLayout((5, 6, 7), "int17"))


def test_unknown_empty_and_missing_paths(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(UnsupportedFormatError, match="notes.txt: unknown volume format '.txt'"):
        load_volume(tmp_path / "notes.txt")
    (tmp_path / "empty.nii").write_bytes(b"")
    with pytest.raises(CorruptFileError, match="empty.nii: the file is empty"):
        load_volume(tmp_path / "empty.nii")
    with pytest.raises(VolumeReadError, match="nothing.nii: no such file or folder"):
        load_volume(tmp_path / "nothing.nii")
    (tmp_path / "fake.nii").write_bytes(os.urandom(400))
    with pytest.raises(CorruptFileError, match="fake.nii"):
        load_volume(tmp_path / "fake.nii")


def test_vtk_file_holding_a_mesh_is_refused(tmp_path):
    from vtkmodules.vtkFiltersSources import vtkSphereSource
    from vtkmodules.vtkIOLegacy import vtkPolyDataWriter

    sphere = vtkSphereSource()
    sphere.Update()
    writer = vtkPolyDataWriter()
    writer.SetInputData(sphere.GetOutput())
    writer.SetFileName(str(tmp_path / "sphere.vtk"))
    writer.Write()
    with pytest.raises(UnsupportedFormatError, match="holds vtkPolyData, not an image volume"):
        load_volume(tmp_path / "sphere.vtk")


def test_legacy_vtk_structured_points(tmp_path):
    from vtkmodules.vtkIOLegacy import vtkStructuredPointsWriter

    volume = small_ct()
    writer = vtkStructuredPointsWriter()
    writer.SetInputData(volume.to_vtk())
    writer.SetFileName(str(tmp_path / "v.vtk"))
    writer.SetFileTypeToBinary()
    writer.Write()
    loaded = load_volume(tmp_path / "v.vtk")
    np.testing.assert_array_equal(loaded.array, volume.array)
    assert np.allclose(loaded.origin, volume.origin) and np.allclose(loaded.spacing, volume.spacing)


def test_writers_never_overwrite_silently(tmp_path):
    volume = small_ct()
    path = save_volume(volume, tmp_path / "v.nrrd")
    before = path.read_bytes()
    with pytest.raises(FileExistsRefusal, match="v.nrrd already exists"):
        save_volume(volume.with_array(volume.array + 1), path)
    assert path.read_bytes() == before
    save_volume(volume.with_array(volume.array + 1), path, overwrite=True)
    assert load_volume(path).array[0, 0, 0] == volume.array[0, 0, 0] + 1
    with pytest.raises(VolumeWriteError, match="cannot write '.png'"):
        save_volume(volume, tmp_path / "v.png")
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert leftovers == []


def test_volume_model_axis_order_and_vtk_conversion():
    array = np.arange(2 * 3 * 4, dtype=np.int16).reshape(2, 3, 4)  # (nz, ny, nx)
    volume = Volume(array, spacing=(0.5, 1.0, 2.0), origin=(1, 2, 3), direction=tilted_direction(30))
    assert volume.dimensions == (4, 3, 2)
    image = volume.to_vtk()
    assert image.GetDimensions() == (4, 3, 2)
    # VTK point id = i + nx * (j + ny * k) holds array[k, j, i].
    assert image.GetPointData().GetScalars().GetValue(3 + 4 * (2 + 3 * 1)) == array[1, 2, 3]
    world = [0.0, 0.0, 0.0]
    image.TransformIndexToPhysicalPoint(3, 2, 1, world)
    assert np.allclose(world, volume.index_to_world((3, 2, 1)))
    back = Volume.from_vtk(image)
    np.testing.assert_array_equal(back.array, array)
    assert np.allclose(back.direction, volume.direction)
    assert np.allclose(volume.world_to_index(volume.index_to_world((1.5, 0.25, 1.0))), (1.5, 0.25, 1.0))


def test_crop_keeps_world_positions():
    volume = small_ct()
    volume.direction = tilted_direction(25.0)
    crop = volume.crop((3, 20), (5, 30), (2, 9))
    assert crop.dimensions == (17, 25, 7)
    assert np.allclose(crop.index_to_world((0, 0, 0)), volume.index_to_world((3, 5, 2)))
    assert crop.array[1, 2, 3] == volume.array[3, 7, 6]
    with pytest.raises(ValueError, match="crop range j = 5..5"):
        volume.crop((0, 4), (5, 5), (0, 2))


def test_padding_keeps_world_positions_and_widens_the_dtype_only_when_needed():
    volume = small_ct()
    volume.direction = tilted_direction(25.0)
    padded = volume.padded(-1024, width=2)
    assert padded.dimensions == tuple(n + 4 for n in volume.dimensions) and padded.array.dtype == volume.array.dtype
    assert np.allclose(padded.index_to_world((2, 2, 2)), volume.index_to_world((0, 0, 0)))
    assert padded.array[2 + 3, 2 + 4, 2 + 5] == volume.array[3, 4, 5]
    assert (padded.array[:2] == -1024).all() and (padded.array[:, :, -2:] == -1024).all()
    assert volume.padded(0.5).array.dtype == np.float32  # not an int16 value
    assert volume.padded(-40000).array.dtype == np.float32  # outside int16's range
    with pytest.raises(ValueError, match="padding width"):
        volume.padded(0, width=0)


def test_volume_validation():
    with pytest.raises(ValueError, match="3D array"):
        Volume(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="spacing must be three positive"):
        Volume(np.zeros((2, 2, 2)), spacing=(1, 0, 1))
    with pytest.raises(ValueError, match="orthonormal"):
        Volume(np.zeros((2, 2, 2)), direction=np.diag([1, 2, 1]))
