"""Push-T: the push_core planner on gym-pusht's Push-T benchmark (``pushbot eval pusht``).

``world`` (the env's frames and the pusher), ``adapter`` (the closed loop, the trials, the
comparison with Diffusion Policy), ``vision`` and ``estimated`` (the object perceived from the
image and estimated online), ``guard`` (the env's internals sealed), ``cli`` (the command).
The design: docs/design/pusht.md.
"""
