"""From a checked RunConfig to a Domain, an ElasticityProblem and probes, checking every name first.

Mesh sources: a built-in generator (meshes.GENERATORS), a gmsh .msh with named
physical groups, or any tetrahedral mesh meshio reads. All name checks (regions,
boundaries, probes inside the body, full and non-overlapping material coverage)
raise ConfigError naming the key, before any solve starts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

import forms
import meshes
from model import compat
from model.activation import ActivationField
from model.config import ConfigError, MeshConfig, RunConfig
from model.domain import Domain, build_domain, read_meshio
from model.expressions import compile_expression, uses_load_factor
from model.fibres import FibreField, solve_laplace
from model.measurements import Probes
from model.problem import ElasticityProblem
from model.targets import TargetField


def load_mesh_data(cfg: MeshConfig) -> meshes.MeshData:
    """The MeshData of a mesh section (call on one rank); errors become ConfigError naming the key."""
    if cfg.generator is not None:
        try:
            return meshes.generate(cfg.generator, **cfg.params)
        except (TypeError, ValueError) as err:
            # generator messages read "<generator>: <parameter>[i] must be ...": name mesh.<parameter>
            message = " ".join(str(err).split())
            param = message.removeprefix(f"{cfg.generator}: ").split(" ")[0].split("[")[0]
            key = f"mesh.{param}" if param in cfg.params else "mesh"
            raise ConfigError(f"{key}: {message}") from None
    assert cfg.file is not None
    try:
        if cfg.file.suffix == ".msh":
            data = meshes.read_msh(cfg.file)
            for key, mapping in (("regions", cfg.regions), ("boundaries", cfg.boundaries)):
                if mapping:
                    raise ConfigError(f"mesh.{key}: a .msh file names its physical groups itself; remove this table")
            return data
        return read_meshio(cfg.file, cfg.regions, cfg.boundaries, cfg.cell_data, cfg.facet_data)
    except ConfigError:
        raise
    except Exception as err:  # noqa: BLE001 - any reader failure is reported against mesh.file
        message = " ".join(str(err).split())  # one line
        if message.startswith("mesh."):
            raise ConfigError(message) from None
        raise ConfigError(f"mesh.file: cannot read {cfg.file}: {message}") from None


def make_domain(cfg: MeshConfig, comm: MPI.Comm) -> Domain:
    """Build the mesh on rank 0 and distribute it; a failure on rank 0 is raised on every rank."""
    data, error, failure = None, None, None
    if comm.rank == 0:
        try:
            data = load_mesh_data(cfg)
        except ConfigError as err:
            error = str(err)
        except Exception as err:  # noqa: BLE001 - re-raised below, after telling the other ranks
            failure = err
    error, other = comm.bcast((error, None if failure is None else f"{type(failure).__name__}: {failure}"), root=0)
    if error is not None:
        raise ConfigError(error)
    if other is not None:
        if failure is not None:
            raise failure
        raise RuntimeError(f"building the mesh failed on rank 0: {other}")
    return build_domain(comm, data)


@dataclass
class Setup:
    domain: Domain
    problem: ElasticityProblem
    probes: Probes
    targets: list[TargetField]
    fibres: fem.Function | None = None
    activation: ActivationField | None = None
    contacts: list[Any] = field(default_factory=list)  # model.contact objects
    sliding: list[Any] = field(default_factory=list)  # model.bones.SlidingConstraint


def _check_fibre_names(config: RunConfig, domain: Domain) -> None:
    for i, m in enumerate(config.materials):
        spec = m.fibres
        if spec is None or spec.type != "laplace":
            continue
        for k in ("origin", "insertion"):
            name = getattr(spec, k)
            if name not in domain.boundaries:
                raise ConfigError(f"material[{i}].fibres.{k}: no boundary named {name!r} in the mesh "
                                  f"(boundaries: {', '.join(sorted(domain.boundaries)) or 'none'})")
        for j, r in enumerate(spec.regions):
            if r != "all" and r not in domain.regions:
                raise ConfigError(f"material[{i}].fibres.regions[{j}]: no region named {r!r} in the mesh "
                                  f"(regions: {', '.join(['all', *sorted(domain.regions)])})")


def _fibre_fields(config: RunConfig, domain: Domain) -> fem.Function | None:
    """One DG0 vector Function a0 for all fibre materials, each setting its region's cells."""
    if not any(m.fibres is not None for m in config.materials):
        return None
    function = fem.Function(compat.function_space(domain.mesh, "DG", 0, (3,)), name="fibre_direction")
    potentials: dict[tuple[str, str, tuple[str, ...]], fem.Function] = {}
    for i, m in enumerate(config.materials):
        spec = m.fibres
        if spec is None:
            continue
        field = FibreField(domain, m.region, function=function)
        key = f"material[{i}].fibres"
        try:
            if spec.type == "constant":
                field.constant(spec.origin, spec.insertion)  # type: ignore[arg-type]
            elif spec.type == "laplace":
                regions = spec.regions or (m.region,)
                which = (str(spec.origin), str(spec.insertion), tuple(regions))
                if which not in potentials:
                    try:
                        potentials[which] = solve_laplace(domain, *which)
                    except ValueError as err:
                        raise ConfigError(f"{key}.regions: {err}; name the regions the fibres run through "
                                          "(fibres.regions)") from None
                field.laplace(which[0], which[1], potential=potentials[which])
            else:
                try:
                    array = np.load(spec.file, allow_pickle=False)  # type: ignore[arg-type]
                except (OSError, ValueError) as err:
                    raise ConfigError(f"{key}.file: cannot read {spec.file}: {str(err).splitlines()[0]}") from None
                field.from_cell_array(array)
        except ValueError as err:
            if isinstance(err, ConfigError):
                raise
            where = {"constant": "insertion", "laplace": "regions", "file": "file"}[spec.type]
            raise ConfigError(f"{key}.{where}: {err}") from None
    return function


def _check_names(config: RunConfig, domain: Domain) -> None:
    regions = sorted(domain.regions)
    boundaries = sorted(domain.boundaries)
    for i, m in enumerate(config.materials):
        if m.region != "all" and m.region not in domain.regions:
            raise ConfigError(f"material[{i}].region: no region named {m.region!r} in the mesh "
                              f"(regions: {', '.join(['all', *regions])})")
    for i, b in enumerate(config.boundaries):
        if b.on not in domain.boundaries:
            raise ConfigError(f"boundary[{i}].on: no boundary named {b.on!r} in the mesh "
                              f"(boundaries: {', '.join(boundaries) or 'none'})")
    for i, f in enumerate(config.body_forces):
        if f.region != "all" and f.region not in domain.regions:
            raise ConfigError(f"body_force[{i}].region: no region named {f.region!r} in the mesh "
                              f"(regions: {', '.join(['all', *regions])})")
    comm = domain.mesh.comm
    tdim = domain.mesh.topology.dim
    num_owned = domain.mesh.topology.index_map(tdim).size_local
    count = np.zeros(num_owned, dtype=np.int32)
    owner = np.full(num_owned, -1)
    for i, m in enumerate(config.materials):
        cells = domain.region_cells(m.region)
        cells = cells[cells < num_owned]
        clash = comm.allreduce(int(np.max(owner[cells], initial=-1)), op=MPI.MAX)
        if clash >= 0:
            raise ConfigError(f"material[{i}].region: {m.region!r} overlaps the region of material[{clash}]")
        owner[cells] = i
        count[cells] += 1
    uncovered = comm.allreduce(int(np.sum(count == 0)), op=MPI.SUM)
    if uncovered:
        raise ConfigError(f"material: {uncovered} cells are in no material's region (use region = \"all\" "
                          f"or cover regions {', '.join(regions)})")


def build(config: RunConfig, comm: MPI.Comm = MPI.COMM_WORLD) -> Setup:
    """Domain, problem with all loads and boundary conditions, and probes of a configuration."""
    domain = make_domain(config.mesh, comm)
    _check_names(config, domain)
    probes = Probes(domain.mesh, {p.name: p.point for p in config.probes})
    if probes.missing:  # the same on every rank (reduced over ranks)
        i = [p.name for p in config.probes].index(probes.missing[0])
        raise ConfigError(f"probe[{i}].point: {list(config.probes[i].point)} is outside the mesh")
    _check_fibre_names(config, domain)
    disc = config.discretization
    fibres = _fibre_fields(config, domain)
    activation = None
    if any("alpha" in forms.FIELDS.get(m.law.name, ()) for m in config.materials):
        activation = ActivationField(domain)
    materials, targets = [], []
    for i, m in enumerate(config.materials):
        law = m.law
        if fibres is not None and "a0" in forms.FIELDS.get(law.name, ()):
            law = dataclasses.replace(law, a0=fibres)
        if activation is not None and "alpha" in forms.FIELDS.get(law.name, ()):
            activation.add(m.region, m.activation)
            law = dataclasses.replace(law, alpha=activation.function)
        if "S" in forms.FIELDS.get(law.name, ()):
            source = m.fields.get("S")
            key = "S_function" if callable(source) else "S_file" if np.ndim(source) == 3 else "S"
            try:
                target = TargetField(domain.mesh, domain.region_cells(m.region), source)
            except (ValueError, forms.ParameterError) as err:
                raise ConfigError(f"material[{i}].{key}: {err}") from None
            law = dataclasses.replace(law, S=target.function)
            targets.append(target)
        materials.append((m.region, law))
    problem = ElasticityProblem(domain, materials, disc.degree, disc.quadrature_degree, disc.formulation)
    for target in targets:
        if target.procedural:
            problem.add_load_hook(target.update)
    if fibres is not None:
        problem.cell_fields["fibre_direction"] = fibres
    if activation is not None:
        problem.add_load_hook(activation.update)
        problem.cell_fields["activation"] = activation.function
    bones = {b.name: b for b in config.bones}
    sliding = []
    for i, b in enumerate(config.boundaries):
        if b.type == "attached":
            from model.bones import attach

            attach(problem, b.on, bones[b.bone].motion)  # type: ignore[index]
        elif b.type == "sliding":
            from model.bones import add_sliding

            bone = bones[b.bone]  # type: ignore[index]
            sliding.append(add_sliding(problem, b.on, bone.obstacle, b.penalty, bone.motion,  # type: ignore[arg-type]
                                       b.quadrature_degree))
        elif b.type == "displacement":
            try:
                if b.value:
                    problem.add_dirichlet(b.on, b.components, b.value, points=b.points)
                else:
                    problem.add_dirichlet(b.on, b.components, [compile_expression(e) for e in b.expression],
                                          [uses_load_factor(e) for e in b.expression], points=b.points)
            except ValueError as err:  # a point that is not a node of the boundary
                j = int(str(err).split()[1]) if str(err).startswith("point ") else 0
                raise ConfigError(f"boundary[{i}].points[{j}]: {err}") from None
        elif b.type == "traction":
            problem.add_traction(b.on, b.value)
        else:
            problem.add_pressure(b.on, b.value[0])
    for f in config.body_forces:
        problem.add_body_force(f.region, f.value)
    contacts = []
    if config.contacts:
        from model.contact import build_contact

        for i, c in enumerate(config.contacts):
            motion = bones[c.bone].motion if c.bone is not None else None
            contacts.append(build_contact(problem, c.spec, motion, key=f"contact[{i}]"))
    return Setup(domain, problem, probes, targets, fibres, activation, contacts, sliding)
