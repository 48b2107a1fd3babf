"""The application: the ``manus`` command line, the lock-step harness, benchmarks, demo.

This package composes the services (it may import them); the services never import it
nor each other.
"""
