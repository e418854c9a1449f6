"""What a solve returns, as data: below the search, which builds it, and above nothing.

* :mod:`.solution`: :class:`~.solution.Hypothesis`, :class:`~.solution.Envelope`,
  :class:`~.solution.Solution`, the status constants (``PROVEN``, ``NOT_REFUTED``), the
  ``OUTLIER`` mark, and the exact truth check of boxes (:func:`~.solution.check_truth`);
* :mod:`.naming`: assignments up to renaming (:func:`~.naming.partition`) and the names a
  solve gives the landmarks a hypothesis adds (``+1``, ``+2``, ...);
* :mod:`.summary`: what the survivors agree on (:func:`~.summary.summarize`) and its JSON.

The search (:mod:`cuikslam.hypotheses`) and the certification (:mod:`cuikslam.witness`)
build these; the presentation layer (the ``results`` package: files, tables, figures, the
truth verdict) and the command line read them. Nothing here imports either.
"""
