"""The report's sections, each ``section(ctx: ReportContext) -> None`` adding its blocks to ``ctx.doc``."""
