"""The bus layer: transports and the servo bus driver."""

__all__: list[str] = []
