"""The robot model and everything below it: kinematics, the model with its effects,
the joint-term dictionary, motion rules, RMS, the closed-form start. It imports
nothing of vision_cal but config and errors (tests/test_architecture.py)."""
