import matplotlib

matplotlib.use("Agg")


def pytest_collection_modifyitems(session, config, items):
    """The documentation's build first (tests/test_docs.py: minutes, in one module): with
    two test processes it runs beside the other tests rather than after them (the files
    are handed out in this order: ``--no-loadscope-reorder`` in pyproject.toml)."""
    items.sort(key=lambda item: item.path.name != "test_docs.py")  # stable: else as found
