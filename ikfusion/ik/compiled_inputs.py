"""The step function's inputs written straight into their slots, only those that changed.

A Gauss-Newton step changes the configuration ``q``, the segment targets and the two reference
configurations; the geometry, the ranges, the posture references and the task weights change
rarely (a sensor dropping out or coming back). Packing all thirteen inputs at every call cost
more than the native arithmetic's setup; here each input that is new is written into its slot
of the :class:`.bound_function.BoundFunction` and the others are left as they stand.

An input is left as it stands only when it is provably the same numbers: the very object
written last time (held, so its identity cannot pass to another array), read-only, and its
memory owned by a read-only array (no view anywhere can write it: NumPy refuses to make a view
of a read-only array writeable). The arrays this project keeps across frames are made so
(:meth:`.compiled.CompiledKinematics.geometry`, the frame weighting's, the ranges' limits);
any other input is written at every call. Writing a slot copies the same float64 numbers that
packing them did, so the outputs are the same bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from operator import attrgetter, is_, itemgetter
from typing import Any

import numpy as np

from .bound_function import BoundFunction


def memory_owner(value: Any) -> np.ndarray | None:
    """The array owning ``value``'s memory (None: not an array's, e.g. a buffer's)."""
    owner = value
    while isinstance(owner, np.ndarray) and not owner.flags.owndata:
        owner = owner.base
    return owner if isinstance(owner, np.ndarray) else None


def picker(indices: Sequence[int]) -> Callable[[Sequence[Any]], tuple[Any, ...]]:
    """A function picking the items ``indices`` of a sequence as a tuple (in C from two on)."""
    if len(indices) >= 2:
        return itemgetter(*indices)
    return lambda items: tuple(items[i] for i in indices)


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only with the array owning its memory.

    For an array made here: a view of a temporary (e.g. ``reshape``'s) would else stay
    writeable through it, and be written into its slot at every call.
    """
    owner = memory_owner(array)
    if owner is not None:
        owner.setflags(write=False)
    array.setflags(write=False)
    return array


class SlotInputs:
    """Inputs of ``call`` set by writing what changed into their slots.

    Args:
        call: The bound step function.
        varying: Inputs new at (nearly) every call: written without a test.
        rotations: Inputs of stacked rotations (k, 3, 3), written as their column-major
            vector (each one's transpose flattened in C order).
        triples: Inputs whose natural shape is (n, 3) (e.g. the ranges' limits).
    """

    def __init__(self, call: BoundFunction, varying: Sequence[int], rotations: Sequence[int],
                 triples: Sequence[int]) -> None:
        self.call = call
        count = call.n_in
        self._slots = [call.input_slot(i) for i in range(count)]
        self._rotations = frozenset(rotations)
        # each slot seen in its input's natural shape; a rotation's as its transposes
        self._views = [s.reshape(-1, 3, 3).swapaxes(1, 2) if i in self._rotations
                       else s.reshape(-1, 3) if i in triples else s
                       for i, s in enumerate(self._slots)]
        self._varying = tuple(varying)
        self._kept = tuple(i for i in range(count) if i not in self._varying)
        # the inputs of each kind picked from a call's inputs at once, and their slots' views
        self._pick_varying, self._pick_kept = picker(self._varying), picker(self._kept)
        self._varying_views = self._pick_varying(self._views)
        self._varying_shapes = tuple(view.shape for view in self._varying_views)
        self._shape = attrgetter("shape")  # (read in a C loop)
        # each kept input: the object last written and the read-only array owning its memory;
        # (None, an array that reads writeable) until one is, and for one not owned by an array
        self._unowned = np.zeros(0)
        self._held: list[Any] = [None] * len(self._kept)
        self._owners = [self._unowned] * len(self._kept)
        self._writeable = attrgetter("flags.writeable")  # (read in a C loop)

    def set(self, inputs: Sequence[Any]) -> BoundFunction:
        """Set every input (in the function's order) and evaluate; the call, outputs ready."""
        varying = self._pick_varying(inputs)
        try:  # (the common case: arrays of their slots' shapes, copied as they stand)
            shaped = tuple(map(self._shape, varying)) == self._varying_shapes
        except AttributeError:  # (not arrays)
            shaped = False
        if shaped:
            for view, value in zip(self._varying_views, varying):
                view[...] = value
        else:
            for i, value in zip(self._varying, varying):
                self._write(i, value)
        kept = self._pick_kept(inputs)
        # (the checks of every kept input in C loops: the same held objects, owners read-only)
        if not all(map(is_, kept, self._held)) or any(map(self._writeable, self._owners)):
            self._write_kept(kept)
        self.call.run()
        return self.call

    def _write_kept(self, kept: Sequence[Any]) -> None:
        """The kept inputs ``kept`` that changed (or may have) written into their slots."""
        held, owners = self._held, self._owners
        for n, (i, value) in enumerate(zip(self._kept, kept)):
            if value is not held[n] or owners[n].flags.writeable:  # (its memory may change)
                self._write(i, value)
                owner = memory_owner(value)
                held[n], owners[n] = (value, owner) if owner is not None else \
                    (None, self._unowned)

    def _write(self, i: int, value: Any) -> None:
        """Input ``i`` written into its slot (read flattened in C order, as packed inputs)."""
        view = self._views[i]
        try:
            if value.shape == view.shape:
                view[...] = value
                return
        except AttributeError:
            pass
        flat = np.ravel(np.swapaxes(value, 1, 2) if i in self._rotations else value)
        if flat.size != view.size:  # refused, never shifted into a neighbour
            raise ValueError(f"input {i}: expected {view.size} numbers, found {flat.size}")
        self._slots[i][:] = flat
