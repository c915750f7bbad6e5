"""How the report is written: the document (markdown and html), its figures, its files (each written whole)."""
