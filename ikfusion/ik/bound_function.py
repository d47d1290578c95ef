"""A CasADi function evaluated on preallocated NumPy buffers (no per-call allocation).

Kept apart from :mod:`.native` (the build): this wrapper does not change the generated code, so
editing it does not invalidate the compiled libraries cached on disk.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np


def column_major(R: np.ndarray) -> np.ndarray:
    """Stacked rotations (k, 3, 3) as CasADi's column-major vector (9k,)."""
    return np.asarray(R).swapaxes(1, 2).reshape(-1)  # the method: no Python-level dispatch


class BoundFunction:
    """A CasADi function evaluated on preallocated NumPy buffers (no per-call allocation).

    Every input is a view of one packed array, so a call that sets them all copies them in one
    ``np.concatenate`` (one NumPy call instead of one per input: a step function has a dozen);
    an input of the wrong size is refused (ValueError), never shifted into its neighbours.
    ``mirrored``: the outputs holding only their lower triangle of a symmetric matrix, read
    (:meth:`output`, :meth:`output_into`, a call) as the whole matrix, each nonzero in both
    triangles (:meth:`nonzeros` stays the lower triangle's).
    """

    def __init__(self, function: ca.Function, mirrored: Sequence[int] = ()) -> None:
        self._buffer, self._evaluate = function.buffer()
        sizes = [function.nnz_in(i) for i in range(function.n_in())]
        self._sizes = tuple(sizes)
        self._packed = np.zeros(sum(sizes))
        ends = np.cumsum(sizes)
        self._inputs = [self._packed[end - size:end] for size, end in zip(sizes, ends)]
        for i, arr in enumerate(self._inputs):
            self._buffer.set_arg(i, memoryview(arr))  # type: ignore[arg-type,call-arg]
        self._dense: list[np.ndarray] = []
        # output -> (its dense array flattened, where its nonzeros go (1 or 2, nnz), the nonzeros)
        self._scattered: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        # the dense vector outputs, one after the other in one array (:meth:`vectors`)
        vector = [function.sparsity_out(i).is_dense() and min(function.size_out(i)) == 1
                  for i in range(function.n_out())]
        self._vectors = np.zeros(sum(function.nnz_out(i) for i, v in enumerate(vector) if v))
        self._vector_at: dict[int, tuple[int, int]] = {}  # output -> (start, size)
        self._stacked: dict[tuple[int, int], np.ndarray] = {}
        at = 0
        for i in range(function.n_out()):
            sp = function.sparsity_out(i)
            dense = np.zeros((sp.size1(), sp.size2()))
            if vector[i]:  # a dense vector: CasADi's column-major nonzeros are the array itself
                dense = self._vectors[at:at + sp.nnz()].reshape(dense.shape)
                self._vector_at[i] = (at, sp.nnz())
                at += sp.nnz()
                self._buffer.set_res(i, memoryview(dense))  # type: ignore[arg-type,call-arg]
            else:
                nz = np.zeros(sp.nnz())
                self._buffer.set_res(i, memoryview(nz))  # type: ignore[arg-type,call-arg]
                rows, cols = (np.array(v, dtype=int) for v in sp.get_triplet())
                flat = rows * sp.size2() + cols
                if i in mirrored:  # (2, nnz): each nonzero at (r, c) and (c, r)
                    flat = np.stack([flat, cols * sp.size2() + rows])
                self._scattered[i] = (dense.reshape(-1), flat, nz)
            self._dense.append(dense)

    def __call__(self, *inputs: np.ndarray) -> list[np.ndarray]:
        """The outputs as dense arrays, overwritten by the next call."""
        self.evaluate(*inputs)
        for flat_dense, flat, nz in self._scattered.values():
            flat_dense[flat] = nz
        return self._dense

    @property
    def n_in(self) -> int:
        """The number of inputs."""
        return len(self._sizes)

    def input_slot(self, i: int) -> np.ndarray:
        """Input ``i``'s buffer (1-D, written in place): what it holds, :meth:`run` reads.

        For a caller that writes only the inputs that changed, straight into their slots.
        """
        return self._inputs[i]

    def run(self) -> None:
        """Evaluate at the inputs as they stand (read the outputs with :meth:`output`)."""
        self._evaluate()

    def set_input(self, i: int, value: np.ndarray) -> None:
        """Set input ``i``; it keeps this value while calls pass fewer inputs."""
        self._inputs[i][:] = value

    def evaluate(self, *inputs: np.ndarray) -> None:
        """Evaluate at the first ``len(inputs)`` inputs (the others keep their last values).

        Each input is read flattened in C order (so ``np.swapaxes(R, 1, 2)`` of stacked
        rotations (k, 3, 3) is their column-major vector, without a copy). Read the outputs
        with :meth:`output`, each made dense only when asked for.
        """
        try:  # every input at once into the packed array, each flattened in C order
            packed = tuple([value.size for value in inputs]) == self._sizes
            if packed:
                np.concatenate(inputs, axis=None, out=self._packed)
        except (AttributeError, TypeError, ValueError):
            packed = False
        if not packed:
            self._set_each(inputs)  # fewer inputs, or one that does not fit (says which)
        self._evaluate()

    def _set_each(self, inputs: tuple[np.ndarray, ...]) -> None:
        for buffer, value in zip(self._inputs, inputs):
            buffer[:] = np.ravel(value)

    def nonzeros(self, i: int) -> np.ndarray:
        """Output ``i``'s structural nonzeros (CasADi's column-major order) of the last call.

        Overwritten by the next call; for a dense vector output, the output itself.
        """
        scattered = self._scattered.get(i)
        return self._dense[i].reshape(-1) if scattered is None else scattered[2]

    def vectors(self, first: int, count: int) -> np.ndarray:
        """Outputs ``first`` .. ``first + count - 1`` of the last call as rows of one array.

        (count, size): a view of the outputs (no copy), overwritten by the next call.

        Raises:
            ValueError: One of them is not a dense vector, or their sizes differ.
        """
        stacked = self._stacked.get((first, count))
        if stacked is None:
            spans = [self._vector_at.get(i) for i in range(first, first + count)]
            if None in spans or len({size for _, size in spans}) != 1:  # type: ignore[misc]
                raise ValueError(f"outputs {first}..{first + count - 1} are not dense vectors "
                                 "of one size")
            start, size = spans[0]  # type: ignore[misc]
            stacked = self._stacked[first, count] = \
                self._vectors[start:start + count * size].reshape(count, size)
        return stacked

    def output_into(self, i: int, out: np.ndarray) -> None:
        """Output ``i`` of the last :meth:`evaluate`, dense, written into ``out`` (its shape).

        :meth:`output` then a copy, the same numbers (a dense vector copied, a sparse output
        scattered into ``out`` zeroed first) without the intermediate dense array.
        """
        scattered = self._scattered.get(i)
        if scattered is None or not out.flags.c_contiguous:
            np.copyto(out, self.output(i))
            return
        _, flat, nz = scattered
        out.fill(0.0)
        out.reshape(-1)[flat] = nz

    def is_dense(self, i: int) -> bool:
        """Whether output ``i`` is a dense vector.

        :meth:`output` then returns the same array each time: its buffer, which each
        evaluation overwrites in place.
        """
        return i not in self._scattered

    def output(self, i: int) -> np.ndarray:
        """Output ``i`` of the last :meth:`evaluate` as a dense array, overwritten by the next."""
        scattered = self._scattered.get(i)
        if scattered is not None:
            flat_dense, flat, nz = scattered
            flat_dense[flat] = nz
        return self._dense[i]
