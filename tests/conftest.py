"""pytest configuration shared by every test folder.

Layout: ``tests/linear``, ``tests/riccati``, ``tests/sampling``, ``tests/models`` and
``tests/nonlinear`` mirror the source tree; cross-cutting tests (textbook cases, peers, reference agreement, properties, the
README, typing, the CLI) stay in ``tests/``.

Imports: with pytest's default ``prepend`` import mode, the directory of this conftest (it has
no ``__init__.py``) is put on ``sys.path`` before any test module is imported, so the shared
helpers here (``modelgen``) import as top-level modules from every subfolder; a test module's
own folder is put there too, so a helper next to the tests that use it imports the same way
(``linear/badinput.py``). The folders are not packages, so module basenames must be unique
across all folders (pytest refuses to collect a second ``test_x.py`` otherwise).

Data files are in ``tests/data``; a test in a subfolder reads them from
``Path(__file__).parent.parent / "data"``.
"""
