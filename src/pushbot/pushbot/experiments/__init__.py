"""Simulation-driven experiments: data generation, training and evaluation.

The modules behind ``pushbot data|train|eval <target>`` (:data:`pushbot.cli.TARGETS`) and the
benchmarks. They drive the pybullet world (``sim_bridge.world``) in-process, train the learned
models whose weights the runtime node packages ship, and score the ROS-free cores; nothing in
the node packages imports them, so the nodes run without the simulator.

- :mod:`.perception_data`, :mod:`.perception_training`, :mod:`.perception_evaluation`: the
  segmentation CNN's data set, training and evaluation (``push_perception.model``);
- :mod:`.affordance_data`, :mod:`.affordance_training`: the learned affordances' data set and
  training (``push_core.learned``, weights in ``push_planner/models``);
- :mod:`.estimator_episodes`, :mod:`.estimator_evaluation`: own-model and pybullet episodes of
  the EKF (``push_core.estimator``) and ``pushbot eval estimator``;
- :mod:`.planner_loop`: the planner's closed loop on ground-truth state in pybullet;
- :mod:`.inprocess` (one trial of :mod:`pushbot.runner.protocol` in-process),
  :mod:`.evaluate` (``pushbot eval push``: the closed-loop experiments, in-process, on Ray or
  through the graph runner :mod:`pushbot.runner.episode`) and its report
  :mod:`.eval_report` (statistics, Tables 5.1 and 5.2, Figs. 5.5-5.7);
- :mod:`.replay`: ``pushbot replay``, a recorded episode bag to video (:mod:`pushbot.viz.render`).
"""
