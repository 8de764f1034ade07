"""scripts/vertex_rounding_table.py: its vertex-map distortion, on a slab whose triangulation the
symmetries preserve (an exact map there distorts by nothing, a wrong one by a lot)."""
import torch

from script_loader import load_script
from shapes import star_slab
from symtorch.detect.group_elements import Geometry
from symtorch.geodesics import GeodesicSolver
from symtorch.sampling import farthest_point_sampling
from symtorch.shapes import symmetry_maps
from symtorch.spectrum import laplacian_spectrum


def test_vertex_distortion_is_zero_for_an_exact_symmetry_and_large_for_a_wrong_map():
    mod = load_script("vertex_rounding_table")
    v, f, mats = star_slab(5, 0.25)
    spec = laplacian_spectrum(v, f, k=30)
    vu = v * spec.scale
    solver = GeodesicSolver(vu, f)
    pts = farthest_point_sampling(torch.as_tensor(vu), 8).numpy()
    geo = Geometry(vu, spec, pts, solver.distances_from(pts), 300, f)
    maps = torch.as_tensor(symmetry_maps(v, mats))
    assert max(mod.vertex_distortion(geo, solver, m) for m in maps) < 0.01
    wrong = torch.roll(torch.arange(len(v)), 57)
    assert mod.vertex_distortion(geo, solver, wrong) > 0.5
