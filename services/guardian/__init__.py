"""The CAN guardian (``manus guardian``): stops the arm when the bridge leaves a sync
unanswered. Imports only :mod:`manus.protocol`, python-can and the standard library."""
