"""Helpers shared by the test modules (import them as ``from helpers.worlds import ...``).

``tests/`` is on ``sys.path`` (pytest's rootdir-relative import of ``tests/conftest.py``), so
this package is ``helpers``. A test module imports from here, never from another test
module, and takes its ROS domain from the ``domain`` / ``domains`` fixtures of
``tests/conftest.py``, never from ``conftest`` itself.

Modules:
    worlds: hand-built and random world states, random behaviour masks.
    trials: the genome, team size and offline runs the trial tests compare with; a lockstep
        trial in a thread (``start_trial``, ``finish``).
    rigs: the mapper rig (a mapper node and a probe feeding it scans and mount states).
    cameras: the synthetic overhead camera the localizer and camera tests share (and its
        ``camera`` fixture, registered by ``tests/conftest.py``).
    blades: behaviour words, and the blade driver's supervisor, driver and probe nodes.
    operator: ``ant-operator`` as a separate process.
    watchers: the operator's watcher of a running trial, the fault matrix's threaded
        watcher, and the occlusion sequence (hiding LEDs through ``/sensors``' parameters).
    limits: resource limits for a child process (``limited``).
    diagnostics: a ``/diagnostics`` probe (``DiagnosticsProbe``: every status, in order and
        the newest by name).
    figures: what a written figure must be (``assert_figure``: decodes, plotted size, not
        blank).
"""
