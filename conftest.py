"""Root pytest configuration, loaded before any test or doctest module is imported.

The FEM problems in the suite are small (hundreds to a few thousand dofs). A
multithreaded BLAS gains nothing on them and, on a 2-core CI machine, threads
contending with the other test process can make a 441×441 eigensolve 100× slower.
One BLAS thread per process keeps the suite's run time predictable.

The README runs the suite on two pytest-xdist workers (``-n 2 --dist loadgroup``). Every
test that takes a TCP port (an OPC UA machine or twin, a Dask scheduler, a port chosen
free for "nothing listens here") carries ``xdist_group("tcp_ports")``, so one worker
runs them all, one after another as in a serial run: a port found free by binding
port 0 and closing is then never taken by the other worker before it is used.
"""
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
