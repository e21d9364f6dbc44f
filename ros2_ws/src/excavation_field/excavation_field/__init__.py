"""Field experiments and long runs on top of the bring-up.

``field_experiment`` reproduces section 6 (``ant-field-experiment``), ``field_bench`` is the
field execution benchmark, ``soak`` the long memory-watching trial (``ant-soak``). They run
trials through ``excavation_bringup`` and, unlike the bring-up, may use the training code
(``ant_evolution``) for their grid references.
"""
