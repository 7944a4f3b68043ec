"""LCM logs of the project's runs: capture (t1-lcm-logger), a reader that survives damaged files, replay of the
logged states into the C++ runtime, and plots. CLI: `python -m sim_hil.lcmlog --help`."""
