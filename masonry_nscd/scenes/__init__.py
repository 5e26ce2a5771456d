"""Scene builders: a case section turned into a block assembly ready to step.

``build_scene(case)`` picks the builder of the case (the arch of ``case.arch`` when it has one,
the vault of ``case.vault``, the assembly of ``case.assembly``, the wall of ``case.wall`` otherwise); each
builder returns a :class:`~masonry_nscd.scenes.scene.Scene`. A new geometry is a new builder
module here and its section in ``case.py``.
"""

from __future__ import annotations


def build_scene(case):
    """The scene of a validated case."""
    if getattr(case, "arch", None) is not None:
        from masonry_nscd.scenes.arch import build_arch

        return build_arch(case)
    if getattr(case, "vault", None) is not None:
        from masonry_nscd.scenes.vault import build_vault

        return build_vault(case)
    if getattr(case, "assembly", None) is not None:
        from masonry_nscd.scenes.assembly import build_assembly

        return build_assembly(case)
    from masonry_nscd.scenes.wall import build_wall

    return build_wall(case)
