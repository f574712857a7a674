"""Model families, one module per paper (import the module you need; nothing heavy is imported here)."""
