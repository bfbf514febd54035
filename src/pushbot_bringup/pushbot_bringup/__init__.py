"""pushbot bringup: the launch file, the parameter files and the launch decision (graph)."""
