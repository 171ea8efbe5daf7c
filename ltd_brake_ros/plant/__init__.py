"""ROS-free plant runtime, its clock passed in (tested on a fake clock, without DDS).

* :mod:`.runner`: the plant thread (chunks paced to the wall clock, overruns, jobs between
  chunks, lock-step, pause/step/reset, auto brake, run policy);
* :mod:`.pacing`: the one wall-clock pacing helper (also used by the replay player);
* :mod:`.recorder`: the recorder's lifecycle, one bag per run;
* :mod:`.diagnostics`: the values of the diagnostics report;
* :mod:`.settings`: what the runtime is told, and the error for a setting it cannot use.
"""
