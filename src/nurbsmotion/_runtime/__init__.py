"""The package's private runtime plumbing, below every stage (private).

File input and output (:mod:`.io`: input checks, atomic outputs that never overwrite),
numba's on-disk caches kept consistent with the sources (:mod:`.jit_cache`), the second
process that compiles the closed loop during a first ``run`` (:mod:`.precompile`),
handing freed memory back to the system (:mod:`.memory`) and work in forked processes:
a worker forked early that prepares, and calls shared between processes
(:mod:`.forked`; a run's figures). Nothing here is public.
"""
