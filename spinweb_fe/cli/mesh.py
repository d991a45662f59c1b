"""``spinweb mesh CASE``: build the mesh only; write DIR/mesh.h5, DIR/mesh_folded.vtu and
DIR/mesh_flat.vtu."""

import logging

from spinweb_fe.cli.common import add_case_args, load_case, out_dir

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser("mesh", help="build the initial mesh and write it (HDF5 + VTU)",
                       description=__doc__)
    add_case_args(p, out=True)
    return p


def run(args) -> int:
    from meshgen.mesh import lumped_mass
    from spinweb_fe.case.scene import build_mesh
    from spinweb_fe.io.mesh import write_mesh_files

    case = load_case(args)
    mesh = build_mesh(case)
    node_mass = lumped_mass(mesh, case.cable.density * case.cable.area)
    paths = write_mesh_files(case, mesh, node_mass, out_dir(args, case))
    log.info("mesh: %d nodes, %d elements, %d arms -> %s", mesh.n_nodes, mesh.n_elems,
             mesh.n_arms, ", ".join(str(p) for p in paths))
    return 0
