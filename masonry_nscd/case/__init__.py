"""The case file: what one simulation of masonry is, validated, with SI units.

A case file is a YAML mapping with the sections below; every value is in SI units (m, Pa, N, J,
s, kg) and every section and field is optional (the defaults are the reference study: Venzal's
1.85 x 1.20 x 0.15 m limestone wall, 11 courses in running bond, ENDO3D blocks, frictional
cohesive joints, 0.5 MPa of vertical stress, 10 mm of imposed horizontal displacement; see
``docs/model.md`` section 1 of the shared documentation)::

    name: wall_0.5MPa            # default: the file's stem
    description: ...
    wall:     geometry of the units, the joints, the bond and the mesh     -> Wall
    blocks:   material of the units (elastic | endo3d | rigid)             -> Blocks, Endo3d
    joint:    joint law (frictional cohesive zone + spring, or Coulomb)    -> Joint
    supports: boundary conditions of the top steel beam                    -> Supports
    loading:  gravity, vertical stress, horizontal displacement stages     -> Loading
    solver:   time step, theta, NLGS tolerance                             -> Solver
    output:   what is written and how often                                -> Output
    arch:     an arch of voussoirs instead of the wall                     -> Arch
    vault:    a barrel vault: the arch in staggered rings along z          -> Vault
    assembly: blocks of hexahedra read from a mesh file                    -> Assembly
    collapse: when an arch run has collapsed                               -> Collapse

A case builds one structure: the wall (the default), or the one whose section it gives
(``arch``, ``vault``, ``assembly``: ``structures/``). Each structure owns its section and the
other parts of the case only it reads (the wall's ``supports`` and push, a limit state's
``collapse`` and growing loads); those of another structure are refused when given, and the
case written back has its own only.

Units are in the field names (``_m``, ``_Pa``, ``_Pa_m`` = Pa/m, ``_J_m2`` = J/m^2, ``_kg_m3``,
``_kg``, ``_s``, ``_m_s`` = m/s, ``_m_s2`` = m/s^2) or, for dimensionless numbers and counts, in
the field's description.

Reading YAML. PyYAML implements YAML 1.1, where ``1e5`` and ``0.3e6`` are *strings* (a 1.1 float
needs a dot and a signed exponent), ``010`` is 8 and ``no``/``on`` are booleans. Case files are
read with a loader that implements the YAML 1.2 core schema instead: ``1e5``, ``0.3e6``,
``-2.5E-3``, ``.5`` are floats; ``10``, ``0x1f``, ``0o17`` are integers; only
``true``/``false`` (any case style) are booleans; ``null``, ``~`` and an empty value are null;
everything else is text. Duplicate keys in a mapping are an error (PyYAML silently keeps the last
one). Numbers given as quoted text ("0.3e6") are still converted by the (lax) validation; true and
false are *not* accepted where a number is expected.

Errors. Every problem in a case file - missing file, YAML syntax, wrong type, out-of-range value,
unknown field, inconsistent geometry, bad ``--set`` override - raises :class:`CaseError`, whose
``messages`` are one readable line each, naming the field path (``joint.d_spring``), the value
given and what is allowed.

The package, by section: ``fields`` (the number types and the base of every section),
``blocks``, ``joint``, ``loading``, ``solver``, ``output``, ``collapse``, ``structures/`` (one
module per structure), ``model`` (the case), ``yaml12`` (the YAML 1.2 reader and writer),
``messages``, ``overrides`` (``--set``), ``files`` (reading and writing case files) and
``reference`` (the reference page and JSON Schema of ``masonry schema``, ``docs/reference/``).

Public API: :class:`Case` (and its sections), :func:`load_case`, :func:`case_from_dict`,
:func:`case_to_yaml`, :func:`read_yaml`, :class:`CaseError`.
"""


from masonry_nscd.case.blocks import Blocks, Endo3d
from masonry_nscd.case.collapse import Collapse
from masonry_nscd.case.errors import CaseError
from masonry_nscd.case.files import case_from_dict, case_to_yaml, load_case
from masonry_nscd.case.joint import Joint, JointRegion, JointScatter
from masonry_nscd.case.loading import (
    BodyForce,
    GravityStage,
    GroundMotionStage,
    HorizontalStage,
    Loading,
    PointLoad,
    Settlement,
    StressStage,
)
from masonry_nscd.case.model import Case
from masonry_nscd.case.output import Output
from masonry_nscd.case.solver import Solver
from masonry_nscd.case.structures.arch import Arch
from masonry_nscd.case.structures.assembly import Assembly, AssemblyMaterial, AssemblySupport
from masonry_nscd.case.structures.vault import Vault
from masonry_nscd.case.structures.wall import (
    Lintel,
    Opening,
    PatternCourse,
    RefineRegion,
    Supports,
    Wall,
)
from masonry_nscd.case.yaml12 import read_yaml

__all__ = [
    "Arch", "Assembly", "AssemblyMaterial", "AssemblySupport", "Blocks", "BodyForce", "Case",
    "CaseError", "Collapse", "Endo3d", "GravityStage", "GroundMotionStage", "HorizontalStage",
    "Joint", "JointRegion", "JointScatter", "Lintel", "Loading", "Opening", "Output",
    "PatternCourse", "PointLoad", "RefineRegion", "Settlement", "Solver", "StressStage",
    "Supports", "Vault", "Wall", "case_from_dict", "case_to_yaml", "load_case", "read_yaml",
]
