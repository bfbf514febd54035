"""Rendering and viewing: a recorded episode bag to video (:mod:`.render`) and the live topics
to Foxglove (:mod:`.view`, ``pushbot view``)."""
