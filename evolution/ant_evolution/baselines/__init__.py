"""Baseline controllers the paper compares ANT with (section 5).

* :mod:`.network`: the flat-array *network program* that fixed networks and NEAT networks
  compile to, its numba decision kernel and the batched scenario runner that uses it;
* :mod:`.fixed`: the fixed-topology feed-forward network (modular activation, weights and
  thresholds evolved by the same GA settings as ANT);
* :mod:`.neat_baseline`: NEAT through neat-python, its genomes compiled to network programs;
* ANT without coarse coding is ``EvolveConfig(coarse_coding=False)``, and the hand-coded
  controller is ``Controller.hand_coded()``: both run in the ANT evaluator unchanged.
"""
