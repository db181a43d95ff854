"""MeshLab's quadric edge collapse on one mesh, timed, for `benches/simplify.rs` to compare with.

    pip install pymeshlab
    python3 benches/meshlab.py MESH FACES OUT.ply

MeshLab's settings match what streak's simplifier keeps: optimal placement, topology, boundaries
and normals (no face flipped). The decimation alone is timed, single-threaded as MeshLab runs it.
"""

import sys
import time

import pymeshlab

source, faces, output = sys.argv[1], int(sys.argv[2]), sys.argv[3]
meshes = pymeshlab.MeshSet()
meshes.load_new_mesh(source)
start = time.perf_counter()
meshes.meshing_decimation_quadric_edge_collapse(
    targetfacenum=faces,
    optimalplacement=True,
    preservenormal=True,
    preservetopology=True,
    preserveboundary=True,
)
seconds = time.perf_counter() - start
print(f"meshlab {source} -> {meshes.current_mesh().face_number()} faces in {seconds:.3f} s")
meshes.save_current_mesh(output)
