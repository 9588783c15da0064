"""locap: optical motion capture in Python.

Read takes (C3D, TRC, CSV) into numpy arrays, label raw point clouds, fill gaps and remove
outliers, solve markers to skeleton motion and write the results, with the same library
stages, defaults and shipped models as the ``locap`` command-line program::

    import locap
    take = locap.read("examples/cmu_01_01_last10s.c3d")
    take.positions.shape            # (frames, markers, 3), mm, NaN where missing
    cleaned = locap.clean(take)     # swaps, outliers, EDM gap filling
    cleaned.write("cleaned.c3d")    # every parameter and analog channel of the input kept
    motion = locap.solve(take)      # the built-in CMU 41-marker solver
    motion.write_bvh("motion.bvh")

A take or file that fails raises :class:`locap.Error` with the CLI's message ``path:
reason``. :mod:`locap.ray` runs one take per task on a Ray cluster.
"""

from ._locap import Error, Motion, Take, __version__, bench_fill, clean, label, read, solve

__all__ = ["Error", "Motion", "Take", "__version__", "bench_fill", "clean", "label", "read", "solve"]
