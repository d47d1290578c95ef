"""One module per batch job kind, each defining ``KIND`` (see :mod:`ikfusion.batch.kinds`)."""
