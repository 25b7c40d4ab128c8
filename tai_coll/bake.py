"""Bake mesh signed-distance grids ahead of time into tai_coll's cache.

    python -m tai_coll.bake MESH [MESH ...] [--resolution 128 | --voxel-size M] [--padding M]
                            [--sign auto|winding|parity|none] [--thickness M]
                            [--arch cpu] [--precision f32]

A later `tc.MeshSDF(MESH, ...)` with the same options, arch precision and cache folder
($TAI_COLL_CACHE_DIR) loads the grid instead of baking it. Prints one line per mesh.
"""

import argparse
import sys


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tai_coll.bake", description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="+", metavar="MESH", help="mesh files trimesh reads (OBJ, STL, PLY, GLB...)")
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--resolution", type=int, default=None, help="nodes along the longest side (default 128)")
    size.add_argument("--voxel-size", type=float, default=None, help="grid spacing in m")
    parser.add_argument("--padding", type=float, default=None, help="margin around the mesh in m (default 4 voxels)")
    parser.add_argument("--sign", default="auto", choices=("auto", "winding", "parity", "none"))
    parser.add_argument("--thickness", type=float, default=0.0, help="shell thickness in m (open surfaces)")
    parser.add_argument("--arch", default="auto", help="Taichi arch for the bake (default auto)")
    parser.add_argument("--precision", default="f32", choices=("f32", "f64"),
                        help="must match the precision of the runs that will use the grid")
    parser.add_argument("--threads", type=int, default=None)
    args = parser.parse_args(argv)

    import tai_coll as tc

    try:
        tc.init(arch=args.arch, precision=args.precision, threads=args.threads)
    except (TypeError, ValueError) as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")  # one line, argparse's status for bad options
    status = 0
    for path in args.meshes:
        try:
            collider = tc.bake_mesh(path, resolution=args.resolution, voxel_size=args.voxel_size,
                                    padding=args.padding, sign=args.sign, thickness=args.thickness)
        except (FileNotFoundError, ValueError) as error:
            print(f"{path}: error: {error}", file=sys.stderr)
            status = 1
            continue
        state = "cached already" if collider.cache_hit else f"baked in {collider.bake_seconds:.3f} s"
        print(f"{path}: {collider.num_faces} faces, grid {list(collider.values.shape)} at "
              f"{collider.voxel_size:.5g} m, sign: {collider.sign_method}; {state} -> {collider.cache_path}")
    return status


if __name__ == "__main__":
    sys.exit(main())
