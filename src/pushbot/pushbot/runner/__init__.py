"""The graph runner: ``pushbot run``, ``up``, ``goal``, ``demo`` and ``doctor`` (one module per
command), the one node launcher (:mod:`.graph_nodes`), the trial definition (:mod:`.protocol`,
which the in-process experiments of :mod:`pushbot.experiments` run too) and the graph episodes
(:mod:`.episode`, :mod:`.client`, :mod:`.faults`) that ``pushbot demo`` and ``pushbot eval push
--graph`` run."""
