"""``spinweb mesh CASE``: build the mesh only; write DIR/mesh.h5, DIR/mesh_folded.vtu and
DIR/mesh_flat.vtu."""

from spinweb_fe.cli.common import add_case_args, load_case, out_dir


def add_parser(sub):
    p = sub.add_parser("mesh", help="build the initial mesh and write it (HDF5 + VTU)",
                       description=__doc__)
    add_case_args(p, out=True)
    return p


def write_mesh_files(case, mesh, folder):
    """Write mesh.h5 (root attributes + /mesh), mesh_folded.vtu and mesh_flat.vtu.

    Point data: ``node_mass`` [kg], ``arm`` [-], ``arm_coord`` [m]; cell data:
    ``rest_length`` [m], ``strain`` [-] (current length / rest length - 1).

    Returns
    -------
    list of Path
        The three files written.
    """
    import h5py
    import numpy as np

    from meshgen.mesh import lumped_mass
    from spinweb_fe.io_mesh import write_mesh_group, write_vtu
    from spinweb_fe.results import write_root_attrs

    folder.mkdir(parents=True, exist_ok=True)
    node_mass = lumped_mass(mesh, case.cable.density * case.cable.area)
    h5_path = folder / "mesh.h5"
    with h5py.File(h5_path, "w") as h5:
        write_root_attrs(h5, case)
        write_mesh_group(h5.create_group("mesh"), mesh, node_mass)
    point_data = {"node_mass": node_mass, "arm": mesh.node_arm.astype(np.int32),
                  "arm_coord": mesh.node_arm_coord}
    paths = [h5_path]
    for name, pos in (("mesh_folded.vtu", mesh.node_pos), ("mesh_flat.vtu", mesh.node_ref)):
        strain = mesh.elem_length(pos) / mesh.elem_rest_len - 1.0
        write_vtu(folder / name, pos, mesh.elem_nodes, point_data,
                  {"rest_length": mesh.elem_rest_len, "strain": strain})
        paths.append(folder / name)
    return paths


def run(args) -> int:
    import logging

    from meshgen.build import build_mesh

    case = load_case(args)
    mesh = build_mesh(case)
    paths = write_mesh_files(case, mesh, out_dir(args, case))
    logging.getLogger("spinweb").info(
        "mesh: %d nodes, %d elements, %d arms -> %s", mesh.n_nodes, mesh.n_elems,
        mesh.n_arms, ", ".join(str(p) for p in paths))
    return 0
