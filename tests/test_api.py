"""The API contract of the README's "Conventions": names, return types, shapes, dtype and device."""
import builtins
import dataclasses
import importlib
import inspect
import pkgutil
import types
import warnings

import pytest
import torch

import symtorch
from symtorch import shapes
from symtorch.detect import DetectConfig, GroupConfig, ReflectionConfig, detect_symmetries
from symtorch.spectrum import laplacian_spectrum


def _modules():
    """Every module of the package but the command line (its functions are argparse handlers)."""
    for m in pkgutil.walk_packages(symtorch.__path__, "symtorch."):
        if m.name.startswith("symtorch.cli") or m.name.endswith("__main__"):
            continue
        try:
            yield importlib.import_module(m.name)
        except ImportError:  # an optional extra (lightning) that is not installed
            continue


def _public_callables():
    """(module, qualified name, function) of every public function and method defined in the package."""
    for mod in _modules():
        for name, obj in vars(mod).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != mod.__name__:
                continue
            if inspect.isfunction(obj):
                yield mod.__name__, name, obj
            elif inspect.isclass(obj):
                for attr, fn in vars(obj).items():
                    if inspect.isfunction(fn) and (not attr.startswith("_") or attr == "__init__"):
                        yield mod.__name__, f"{name}.{attr}", fn


# ------------------------------------------------------------------------------------------ names
def test_all_is_explicit_and_complete():
    assert isinstance(symtorch.__all__, list) and len(set(symtorch.__all__)) == len(symtorch.__all__)
    missing = [n for n in symtorch.__all__ if not hasattr(symtorch, n)]
    assert not missing, missing
    # every public object the package imports into its namespace is listed (submodules are not)
    unlisted = [n for n, obj in vars(symtorch).items()
                if not n.startswith("_") and not isinstance(obj, types.ModuleType) and n not in symtorch.__all__]
    assert not unlisted, f"add to symtorch.__all__ (or import under a private name): {unlisted}"


def test_star_import_binds_only_the_api_and_no_builtin():
    ns: dict = {}
    exec("from symtorch import *", ns)
    names = set(ns) - {"__builtins__"}
    assert names == set(symtorch.__all__)
    assert not names & set(dir(builtins)), names & set(dir(builtins))  # e.g. `eval` stays the builtin
    assert not any(isinstance(ns[n], types.ModuleType) for n in names)


def test_no_function_shadows_a_module():
    import symtorch.descriptors as d

    assert isinstance(d, types.ModuleType) and callable(d.hks)
    for m in pkgutil.iter_modules(symtorch.__path__):
        obj = getattr(symtorch, m.name, None)
        assert obj is None or isinstance(obj, types.ModuleType), f"symtorch.{m.name} is {type(obj).__name__}"


def test_one_name_for_the_symmetry_matrix():
    """Symmetry matrices are ``fmap`` / ``fmaps`` in signatures (``C`` only inside math code)."""
    banned = {"mats", "S", "sym_fmap"}
    offenders = [f"{mod}.{name}({p})" for mod, name, fn in _public_callables()
                 for p in inspect.signature(fn).parameters if p in banned]
    assert not offenders, offenders
    fields = {f.name for f in dataclasses.fields(symtorch.Symmetry)}
    assert "fmap" in fields and "C" not in fields


def test_no_return_flags():
    """Several results come back as a NamedTuple or dataclass, never as a tuple whose length a flag sets."""
    offenders = [f"{mod}.{name}({p})" for mod, name, fn in _public_callables()
                 for p in inspect.signature(fn).parameters if p.startswith("return_")]
    assert not offenders, offenders


def test_detect_takes_a_config_and_rejects_unknown_knobs():
    assert dataclasses.is_dataclass(DetectConfig) and DetectConfig.__dataclass_params__.frozen
    for cls in (ReflectionConfig, GroupConfig):
        assert cls.__dataclass_params__.frozen
    cfg = DetectConfig().with_keywords(k_refine=40, min_score=0.7, n_refine=0)
    assert cfg.k_refine == 40 and cfg.reflection.min_score == 0.7 and cfg.reflection.n_candidates == 1
    v, f = shapes.mirror_blob(1)
    with pytest.raises(TypeError, match="generator"):  # detection draws nothing: no generator to pass
        detect_symmetries(v, f, generator=torch.Generator())
    with pytest.raises(ValueError, match="verify"):
        ReflectionConfig(verify="nope")


# ------------------------------------------------------------------------------------------ results
@pytest.fixture(scope="module")
def blob():
    v, f = shapes.mirror_blob(2)
    return v, f, laplacian_spectrum(v, f, k=110)


@pytest.fixture(scope="module")
def both_paths(blob):
    v, f, spec = blob
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return detect_symmetries(v, f, spectrum=spec), detect_symmetries(v, f, spectrum=spec, mode="group")


def test_result_shapes_do_not_depend_on_the_path(blob, both_paths):
    _, _, spec = blob
    auto, group = both_paths
    assert auto.diagnostics.path == "reflection" and group.diagnostics.path == "group"
    assert auto.group.name == group.group.name == "Cs"
    assert auto.fmaps.shape == group.fmaps.shape, (auto.fmaps.shape, group.fmaps.shape)
    K = auto.fmaps.shape[-1]
    for res in (auto, group):
        assert res.spectrum is spec  # the spectrum the detection ran on, whichever path
        assert res.bands[0].start == 0 and res.bands[-1].stop == K
        assert res.to_dict()["k"] == K
    # the same maps, and so (up to the refinement's rounding) the same matrices
    assert torch.equal(auto.p2ps, group.p2ps)
    torch.testing.assert_close(auto.fmaps, group.fmaps, atol=1e-6, rtol=0)


def test_results_are_typed_torch_records(both_paths):
    for res in both_paths:
        assert dataclasses.is_dataclass(res) and isinstance(res.group, symtorch.GroupInfo)
        assert isinstance(res.fmaps, torch.Tensor) and isinstance(res.p2ps, torch.Tensor)
        assert res.p2ps.dtype == torch.long and isinstance(res.group.table, torch.Tensor)
        for s in res.symmetries:
            assert s.C is s.fmap  # the mathematical name, kept as an alias
        d = res.to_dict()  # JSON-ready: plain lists and numbers
        assert d["group"]["name"] == res.group.name and d["group"]["order"] == len(d["symmetries"])
        assert isinstance(res.info, dict)  # the diagnostics as a plain dict


def test_outputs_follow_the_spectrum_dtype_and_device(blob, device):
    v, f, spec = blob
    res = detect_symmetries(v, f, spectrum=spec.to(device=device, dtype=torch.float32), mode="reflection")
    assert res.fmaps.dtype == torch.float32 and res.spectrum.evecs.dtype == torch.float32
    assert res.fmaps.device == res.p2ps.device == res.group.table.device == device
    assert detect_symmetries(v, f, mode="reflection").fmaps.dtype == torch.float64  # solved here: float64
