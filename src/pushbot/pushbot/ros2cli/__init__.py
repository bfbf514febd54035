"""The ros2cli stand-ins (``ros2cli`` is not on PyPI): ``pushbot topic``, ``node``, ``param``,
``service`` and ``bag``, one module per command, with the graph discovery (:mod:`.discovery`)
and the one message codec (:mod:`.messages`) they share."""
