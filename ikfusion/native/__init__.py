"""Native code built on the user's machine.

The compile-and-verify path (:mod:`.build`) and the hand-written C kernels loaded with ctypes
(:mod:`.kernel`). Every native piece is optional: without a C compiler, with
``IKFUSION_NO_COMPILE`` set or after a failed build its caller runs the NumPy path, which stays
the reference.
"""
