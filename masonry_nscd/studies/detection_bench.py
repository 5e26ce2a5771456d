"""The cost of contact detection on a case's blocks: the benchmark behind ``masonry
bench-detection``.

The case's scene is built once; then the joints of its bodies are found again
(:func:`masonry_nscd.model.detection.find_joints`: planar patches, a uniform-grid broad phase,
facing pairs) and their contact points made (:func:`~masonry_nscd.model.detection.joint_points`
with the case's rule and points per face), ``repeats`` times each; the medians (s) are reported
with the counts of blocks, joints and points. Both steps grow with the number of blocks, not its
square (the broad phase compares only patches that share a cell). They are timed as a run makes
them, before any contact point exists: the scene's own points are dropped first, and each
repetition's before the next (Python's collector walks every live object).
"""

from __future__ import annotations

import gc
import statistics
import time
from dataclasses import dataclass

from masonry_nscd.contact import laws
from masonry_nscd.model.detection import find_joints, joint_points
from masonry_nscd.scenes import build_scene


@dataclass
class DetectionTimes:
    """Counts and median times (s) of one case's contact detection."""

    blocks: int
    joints: int
    points: int
    build_s: float  # the whole scene, once
    find_joints_s: list[float]
    joint_points_s: list[float]

    @property
    def detection_s(self) -> float:
        """Median of find_joints plus median of joint_points (s)."""
        return statistics.median(self.find_joints_s) + statistics.median(self.joint_points_s)

    def lines(self) -> list[str]:
        """What the command prints."""
        med = statistics.median
        find, points = self.find_joints_s, self.joint_points_s
        per_block_ms = 1e3 * self.detection_s / max(self.blocks, 1)
        return [f"blocks {self.blocks}, joints {self.joints}, contact points {self.points}",
                f"scene built in {self.build_s:.2f} s (once)",
                f"find_joints: median {med(find):.2f} s of {len(find)}",
                f"joint_points: median {med(points):.2f} s of {len(points)}",
                f"contact detection: {self.detection_s:.2f} s, {per_block_ms:.2f} ms per block"]


def detection_times(case, repeats: int = 3) -> DetectionTimes:
    """Time the contact detection of ``case``'s scene (module docstring)."""
    t0 = time.perf_counter()
    scene = build_scene(case)
    build_s = time.perf_counter() - t0
    bodies = scene.bodies
    del scene  # its points: a run detects before any exists (the collector walks them all)
    section = case.structure_section
    gap = float(getattr(section, "joint_thickness_m", 0.0) or 0.0)
    n_gauss = int(getattr(section, "contact_points_per_face", 2))
    find_s, points_s = [], []
    counts = (0, 0)
    for _ in range(repeats):
        gc.collect()
        t0 = time.perf_counter()
        joints = find_joints(bodies, max_gap=gap).joints
        t1 = time.perf_counter()
        points = joint_points(bodies, joints, lambda joint, ant: (0, laws.KIND_JOINT, 0),
                              n_gauss=n_gauss, rule=case.contact_point_rule)
        t2 = time.perf_counter()
        find_s.append(t1 - t0)
        points_s.append(t2 - t1)
        counts = (len(joints), len(points))
        del joints, points
    blocks = sum(not getattr(b, "support", False) for b in bodies)
    return DetectionTimes(blocks, *counts, build_s, find_s, points_s)
