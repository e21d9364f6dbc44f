"""Trials and the dome: assembles the node suite into a graph and launches it.

The one package that imports every node package, and no training code
(docs/architecture.md, "Packages" and "The trial graph"):

* :mod:`~excavation_bringup.kinds`: the registry of node kinds;
* :mod:`~excavation_bringup.deployment`: what a run runs, from options or a site file;
* :mod:`~excavation_bringup.profiles`: the wall-clock fallbacks of each way of running;
* :mod:`~excavation_bringup.nodes`: one node spec function per kind;
* :mod:`~excavation_bringup.graph`: the lockstep and continuous graphs, the only place a run
  is assembled;
* :mod:`~excavation_bringup.launch`, :mod:`~excavation_bringup.supervise`: the composed and
  the process launcher, and the dome's process supervisor;
* :mod:`~excavation_bringup.trial` (``ant-trial``), :mod:`~excavation_bringup.dome`
  (``ant-dome``), :mod:`~excavation_bringup.site` (site files),
  :mod:`~excavation_bringup.view` (``ant-view``), :mod:`~excavation_bringup.generate`
  (``make params``).
"""
