"""The add-on's version, one constant: the package's ``__version__``, and what the farm's job
files carry (`farm.store`), read without importing the package's top (`register`)."""

__version__ = "0.1.0"
