"""spinweb: explicit cable finite elements for the centrifugal deployment of spinning space webs."""

__version__ = "0.1.0"
FORMAT_VERSION = 1
