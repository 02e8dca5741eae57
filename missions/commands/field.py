"""`uavsearch field`: grid a real field drawn in QGroundControl, Google Earth or a GIS tool.

Reads FILE (.plan, .kml, .kmz, .geojson), lays the grid over it, prints its size and masked
share, writes DIR/field.json (what `--field` takes) and DIR/field.png (the preview). A bad file
gets one line naming it and what is wrong, and exit status 1."""

from __future__ import annotations

from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def field(
        file: Path = typer.Argument(..., help="The field: a QGroundControl .plan, a .kml / .kmz or a .geojson.",
                                    show_default=False),
        cell_m: float = typer.Option(2.0, "--cell-m", help="Cell size in metres (the grid world's cell)."),
        heading: float | None = typer.Option(
            None, "--heading", help="Bearing of the grid's -y axis (the move f), degrees from north "
                                    "(default: the minimum-area bounding rectangle's).", show_default=False),
        out: Path = typer.Option(Path("out/field"), "--out", help="Directory for field.json and field.png."),
    ) -> None:
        """Read a polygon field (holes and exclusions as no-fly zones) and grid it."""
        from sim.field import FieldError, read_shapes
        from sim.field.model import build_field, write_field
        from sim.field.preview import write_png

        try:
            shapes = read_shapes(file)
            f = build_field(shapes, file, cell_m, heading)
        except FieldError as e:
            typer.echo(f"error: {e}", err=True)
            raise typer.Exit(1) from None
        n = f.counts()
        total = f.width * f.height
        typer.echo(f"{file}: {f.source}")
        how = "given" if heading is not None else "the minimum-area rectangle's"
        typer.echo(f"grid {f.width} x {f.height} = {total} cells of {f.cell_m:g} m at heading "
                   f"{f.heading_deg:.2f} deg ({how}); cell (0, 0) at {f.origin.lat_deg:.7f}, {f.origin.lon_deg:.7f}")
        typer.echo(f"searchable {n['searchable']} cells ({100 * n['searchable'] / total:.1f} %), masked "
                   f"{100 * (total - n['searchable']) / total:.1f} %: outside {n['outside']}, "
                   f"forbidden {n['forbidden']} (no-fly zones: {len(f.no_fly)})")
        outer, rings = f.rings_ne()
        import shapely

        field_poly = shapely.Polygon(outer[:, ::-1])
        away = [z for z, r in zip(f.no_fly, rings, strict=True)
                if not shapely.intersects(field_poly, shapely.Polygon(r[:, ::-1]))]
        if away:
            typer.echo(f"warning: {len(away)} no-fly polygon(s) lie outside the field and mark no cell "
                       f"({', '.join(z.name or z.kind for z in away)})", err=True)
        config = {"file": str(file), "cell_m": cell_m, "heading": heading}
        try:
            write_field(out / "field.json", f, config)
            write_png(out / "field.png", f, title=file.name)
        except OSError as e:
            typer.echo(f"error: cannot write to {out}: {e.strerror or e}", err=True)
            raise typer.Exit(1) from None
        typer.echo(f"wrote {out / 'field.json'} and {out / 'field.png'}")
