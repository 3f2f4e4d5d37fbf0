"""Run Debian's dxf2gcode (package `dxf2gcode`) headless on many drawings.

Run by Debian's own /usr/bin/python3 (dxf2gcode is a PyQt5 program of that
interpreter), never imported by the project's scripts:

    QT_QPA_PLATFORM=offscreen HOME=SCRATCH /usr/bin/python3 dxf2gcode_batch.py \
        OPTIONS.json IN1.dxf OUT1.ngc [IN2.dxf OUT2.ngc ...]

This is dxf2gcode's own command line (`dxf2gcode -q -e OUT IN`) done for
many files in one process: its main window is built once without being
shown, and each drawing is loaded and exported with its own code. Two
things differ from the command line, neither touching the G-code:

- QFont is given an integer point size: dxf2gcode 20191025 passes a float
  (route labels on its canvas), which PyQt5 5.15 on Python 3.11 refuses,
  so the packaged command line fails on every drawing before export.
- OPTIONS.json sets configuration values before the window is built, as a
  user does in its configuration dialogs: {"config": {"Section": {"key":
  value}}, "postpro": {"Section": {"key": value}}}. The files are written
  under $HOME/.config/dxf2gcode (HOME is a scratch directory).
- A message box returns at once instead of waiting for a click.

Prints one line per drawing, `ok OUT` or `failed IN: reason`, and exits 0.
"""

import importlib.machinery
import importlib.util
import json
import logging
import os
import sys

from PyQt5 import QtGui

_QFont = QtGui.QFont


class _IntSizeFont(_QFont):
    def __init__(self, *a):
        if len(a) >= 2 and isinstance(a[1], float):
            a = (a[0], max(1, int(round(a[1])))) + tuple(a[2:])
        super().__init__(*a)


QtGui.QFont = _IntSizeFont

# A dialog would wait for a click forever: answer every one at once.
from PyQt5 import QtWidgets  # noqa: E402

QtWidgets.QMessageBox.exec_ = lambda self: 0
for _name in ("warning", "critical", "information", "question"):
    setattr(QtWidgets.QMessageBox, _name, staticmethod(lambda *a, **k: 0))


def set_options(var_dict, options):
    for section, values in options.items():
        for key, value in values.items():
            var_dict[section][key] = value
    var_dict.write()


def main():
    options = json.load(open(sys.argv[1]))
    pairs = sys.argv[2:]
    if not pairs or len(pairs) % 2:
        sys.exit("usage: dxf2gcode_batch.py OPTIONS.json IN OUT [IN OUT ...]")

    import dxf2gcode.globals.globals as g
    from dxf2gcode.globals.config import MyConfig
    from dxf2gcode.postpro.postprocessorconfig import MyPostProConfig
    from PyQt5.QtWidgets import QApplication

    g.folder = os.path.join(os.path.expanduser("~"), ".config/dxf2gcode")
    app = QApplication(["dxf2gcode"])
    g.config = MyConfig()
    set_options(g.config.var_dict, options.get("config", {}))
    pp = MyPostProConfig()
    pp.create_default_config()
    set_options(pp.var_dict, options.get("postpro", {}))
    g.config = MyConfig()  # read back, as dxf2gcode does at start
    g.quiet = True

    loader = importlib.machinery.SourceFileLoader("dxf2gcode_app", "/usr/bin/dxf2gcode")
    spec = importlib.util.spec_from_loader("dxf2gcode_app", loader)
    d2g = importlib.util.module_from_spec(spec)
    loader.exec_module(d2g)
    # What dxf2gcode's main block imports into its globals (2D canvas).
    from dxf2gcode_ui5 import Ui_MainWindow
    from dxf2gcode.gui.canvas2d import MyGraphicsScene
    from dxf2gcode.gui.canvas2d import ShapeGUI as Shape
    d2g.Ui_MainWindow, d2g.MyGraphicsScene, d2g.Shape = Ui_MainWindow, MyGraphicsScene, Shape
    logging.getLogger().setLevel(logging.ERROR)

    window = d2g.MainWindow(app)
    g.window = window
    for src, out in zip(pairs[0::2], pairs[1::2]):
        if not os.path.isfile(src):
            print(f"failed {src}: no such file", flush=True)
            continue
        try:
            window.filename = src
            window.load()
            rc = window.exportShapes(None, out)
        except Exception as e:  # one drawing's failure is reported, not fatal
            print(f"failed {src}: {type(e).__name__}: {e}", flush=True)
            continue
        if rc == 0 and os.path.isfile(out):
            print(f"ok {out}", flush=True)
        else:
            print(f"failed {src}: export returned {rc}", flush=True)


if __name__ == "__main__":
    main()
