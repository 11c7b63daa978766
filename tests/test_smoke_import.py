def test_all_modules_import():
    import importlib
    import pkgutil

    import drawer_lib

    for m in pkgutil.walk_packages(drawer_lib.__path__, "drawer_lib."):
        importlib.import_module(m.name)
