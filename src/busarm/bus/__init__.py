"""The bus layer: transports and the servo bus driver."""
