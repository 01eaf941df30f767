"""The estimation core shared by every method: small-matrix linear algebra, predictions,
measurement updates, the RTS backward step and the discretisations of the process models.

Compiled with numba (``nogil``) where the methods call them per sample.  The maths is in
``docs/estimation.md``.
"""
