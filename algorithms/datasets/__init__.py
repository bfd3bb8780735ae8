"""Synthetic data for tests and benchmarks of the algorithms, without the application (:mod:`.volumes`).

Volumes and fields: voxel-model families of source 000, random classified volumes of source 004, analytic
fields with known areas and volumes, and the CT head phantom's array (see :mod:`.volumes`).
"""
