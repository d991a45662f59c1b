"""meshgen: MATLAB-style generation of spinning-web meshes (flat web, star fold, coil on hub)."""

from meshgen.mesh import Mesh, lumped_mass

__all__ = ["Mesh", "lumped_mass"]
