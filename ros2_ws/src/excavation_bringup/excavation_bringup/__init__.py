"""Trials and the dome (DESIGN.md, "Layout"): the one package that imports every node package.

* :mod:`excavation_bringup.trial`: ``ant-trial``, a whole trial through the node suite
  (composed in one process or each node its own process);
* :mod:`excavation_bringup.perception`: the synthetic camera and laser, localiser and mapper
  composed for ``--perception full``.
"""
