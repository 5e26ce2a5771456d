"""The studies: many runs of a case, and the tables and figures made of them.

Each study is a command of the CLI and a module here:

* :mod:`.bench`: run time against error of settings around a case's, the scaling with the
  size of the wall, the start-up time (``masonry bench``, ``masonry bench-scaling``);
* :mod:`.sweep`: a case run for every combination of some fields' values (``masonry sweep``);
* :mod:`.sensitivity`: sensitivity indices of one output to some parameters, with SALib
  (``masonry sensitivity``);
* :mod:`.stress`: a matrix of variants of a small wall, each judged (``masonry stress-test``);
* :mod:`.calibrate`: the value of one parameter that gives a target initial stiffness
  (``masonry calibrate``);
* :mod:`.threshold`: the value of one parameter between standing and collapse
  (``masonry threshold``);
* :mod:`.check_cases`: every shipped case against its record (``masonry check-cases``).

The studies sit above the run (:mod:`masonry_nscd.run`) and its folder, and below the CLI.
"""
