"""Rigid-block limit analysis of a case's scene, beside the NSCD run on the same case file.

The scene's bodies taken as rigid and its contact points as interface points
(:mod:`.statics`), the friction cone as a pyramid (:mod:`.friction`), the static theorem as a
linear programme solved by HiGHS and its dual, the mechanism (:mod:`.lp`), the joints that
hinge and slide named as the NSCD summary names them (:mod:`.mechanism`), the
non-associative collapse load by following the load from rest on the joints' springs
(:mod:`.path`, its loops over the points in :mod:`.path_kernels`), the command's
analysis and files (:mod:`.analysis`), the picture (:mod:`.picture`), and the smallest value of
a case parameter for which the dead loads can be carried (:mod:`.thickness`). See
``docs/limit.md``.
"""
