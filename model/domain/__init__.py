"""The computational domain: meshes read or generated, distributed with named regions and boundaries,
and probes at reference points."""

from model.domain.distribute import Domain, build_domain
from model.domain.probes import Probes, nearest_surface_points, place_probes
from model.domain.readers import exterior_triangles, load_mesh_data, make_domain, read_meshio

__all__ = ["Domain", "Probes", "build_domain", "exterior_triangles", "load_mesh_data", "make_domain",
           "nearest_surface_points", "place_probes", "read_meshio"]
