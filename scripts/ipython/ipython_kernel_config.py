# IPython kernel configuration of the project's virtual environment: scripts/setup.sh installs it as
# .venv/etc/ipython/ipython_kernel_config.py, so it applies to the kernels of this venv only.
#
# First-use messages must never change what a notebook cell outputs (nbval compares them): matplotlib
# announces a font-cache build on stderr when the build takes more than 5 s, i.e. only on a cold
# cache on a slow or busy machine.  The build still happens; only its announcement is silenced.
c = get_config()  # noqa: F821  (provided by IPython when it loads this file)
c.InteractiveShellApp.exec_lines = [
    "import logging as _logging; _logging.getLogger('matplotlib.font_manager').setLevel(_logging.ERROR); del _logging",
]
