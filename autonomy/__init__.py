"""The assistance: arbitration, reactive Bayesian network, contextual-task recognition.

Pure numpy, scipy and scikit-learn. A mode sees plain observations (duck-typed:
``obs.points``, ``obs.pose``, ``obs.components``), never pybullet, so the same
code could drive a real robot.
"""
