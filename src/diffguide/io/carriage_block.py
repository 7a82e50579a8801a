"""The ``[carriage]`` section by catalogue name or by datasheet values.

A machine file may describe its runner block in three ways, which :func:`resolve_catalogue`
turns into the ordinary internal keys of :data:`~diffguide.io.config_spec.KEYS` before the file
is validated:

- ``block = "<family> <size> <type>"`` and ``preload_class = "..."``: a block of the package's
  catalogue table (:mod:`diffguide.guideway.catalogue`), its contact geometry calibrated to the
  published rigidity (or to ``rigidity_N_um``, for a block whose sources publish none);
- a block not in the table, by its datasheet alone: ``capacity_N``, ``preload_fraction``,
  ``rigidity_N_um`` and the envelope ``block_height_mm``, ``block_width_mm``,
  ``body_length_mm``, ``rail_width_mm``, ``rail_height_mm`` (``law = "roller"`` for rollers);
- the internal keys themselves (the default), which also override the first two key by key.

The carriage footprint ``[guideway] carriage_footprint_mm`` defaults to the block's steel body
(length × width) when the file does not give it. Where each value came from is returned as a
provenance mapping (stored in the configuration under ``"catalogue"``).
"""

from .config_spec import KEYS, _si, _user

#: Catalogue keys of ``[carriage]``: ``{key: (default, kind, low, high, help)}``.
CATALOGUE_KEYS: dict[str, tuple] = {
    "block": (None, "name", None, None, 'catalogue block, "<family> <size> <type>"'),
    "preload_class": (None, "name", None, None, "the block's preload class, e.g. ZA"),
    "rigidity_N_um": (
        None,
        "float",
        1.0,
        1e5,
        "datasheet block, or a catalogue block without one: radial rigidity at its preload (N/µm)",
    ),
    "block_height_mm": (None, "float", 5.0, 1000.0, "datasheet block: rail foot to block top"),
    "block_width_mm": (None, "float", 5.0, 1000.0, "datasheet block: block width"),
    "body_length_mm": (None, "float", 5.0, 1000.0, "datasheet block: steel body length"),
    "rail_width_mm": (None, "float", 2.0, 500.0, "datasheet block: rail width"),
    "rail_height_mm": (None, "float", 2.0, 500.0, "datasheet block: rail height"),
}
_DATASHEET = (
    "rigidity_N_um",
    "block_height_mm",
    "block_width_mm",
    "body_length_mm",
    "rail_width_mm",
    "rail_height_mm",
)


def _field(key: str) -> tuple[str, float | None]:
    path, scale = KEYS["carriage"][key][:2]
    return path.split(".", 1)[1], scale


def _explicit(body: dict, source: str, check, schema: dict) -> dict:
    """The internal keys a file gives, validated, as SI :class:`CarriageSpec` fields."""
    out = {}
    for key, value in body.items():
        if key in CATALOGUE_KEYS:
            continue
        if key not in schema:
            allowed = ", ".join([*schema, *CATALOGUE_KEYS])
            raise ValueError(f"{source}: key 'carriage.{key}' is unknown; allowed: {allowed}")
        field, scale = _field(key)
        out[field] = _si(check(value, schema[key], f"{source}: key 'carriage.{key}'"), scale)
    return out


def _catalogue_values(body: dict, source: str, check) -> dict:
    out = {}
    for key in CATALOGUE_KEYS.keys() & body.keys():
        spec, where = CATALOGUE_KEYS[key], f"{source}: key 'carriage.{key}'"
        if spec[1] == "name":
            if not isinstance(body[key], str) or not body[key].strip():
                raise ValueError(f"{where}: must be a non-empty string, got {body[key]!r}")
            out[key] = body[key]
        else:
            out[key] = check(body[key], spec, where)
    return out


def _block(cat: dict, explicit: dict, source: str):
    """The block (catalogue or datasheet) and its preload class."""
    from ..guideway.catalogue import catalogue_block, datasheet_block

    where = f"{source}: [carriage]"
    given = [k for k in _DATASHEET if k in cat]
    if "block" in cat:
        if given and given != ["rigidity_N_um"]:
            raise ValueError(
                f"{where}: give either 'block' or the datasheet keys ({', '.join(given)}), not both"
            )
        try:
            block = catalogue_block(cat["block"])
        except ValueError as exc:
            raise ValueError(f"{source}: key 'carriage.block': {exc}") from None
        cls = cat.get("preload_class")
        if cls is None or cls not in block.preload_classes:
            got = "missing" if cls is None else f"{cls!r} is not allowed"
            raise ValueError(
                f"{source}: key 'carriage.preload_class': {got} for {block.name}; allowed: "
                f"{', '.join(block.preload_classes)}"
            )
        return block, cls
    if "preload_class" in cat:
        raise ValueError(f"{source}: key 'carriage.preload_class' needs 'carriage.block'")
    need = [k for k in _DATASHEET if k not in cat]
    need += [
        k
        for k, f in (("capacity_N", "capacity"), ("preload_fraction", "preload_fraction"))
        if f not in explicit
    ]
    if need:
        raise ValueError(
            f"{where}: a datasheet block needs {', '.join(need)} too (or name a catalogue 'block')"
        )
    mm = 1e-3
    try:
        block = datasheet_block(
            element="roller" if explicit.get("law") == "roller" else "ball",
            capacity=explicit["capacity"],
            preload_fraction=explicit["preload_fraction"],
            rigidity=cat["rigidity_N_um"] * 1e6,
            block_height=cat["block_height_mm"] * mm,
            block_width=cat["block_width_mm"] * mm,
            body_length=cat["body_length_mm"] * mm,
            rail_width=cat["rail_width_mm"] * mm,
            rail_height=cat["rail_height_mm"] * mm,
        )
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return block, "datasheet"


def resolve_catalogue(raw: dict, source: str, check, schema: dict) -> tuple[dict, dict | None]:
    """``raw`` with a catalogue or datasheet ``[carriage]`` replaced by its internal keys.

    Arguments:
        raw: the file's mapping (user units). source: the file's name, for messages.
        check: ``check(value, (default, kind, low, high, help), where)`` -> the validated value.
        schema: the ``[carriage]`` schema of :func:`~diffguide.io.config_spec.schema`.

    Returns:
        ``(raw, info)``: ``info`` is ``None`` when the section names no block, otherwise
        ``{"block", "preload_class", "provenance": {key: text}}``.
    """
    from ..guideway.catalogue import calibrate_block

    body = raw.get("carriage") if isinstance(raw, dict) else None
    if not isinstance(body, dict) or not CATALOGUE_KEYS.keys() & body.keys():
        return raw, None
    cat = _catalogue_values(body, source, check)
    explicit = _explicit(body, source, check, schema)
    block, cls = _block(cat, explicit, source)
    rigidity = cat.get("rigidity_N_um") if "block" in cat else None
    try:
        spec, prov = calibrate_block(
            block, cls, rigidity=None if rigidity is None else rigidity * 1e6, **explicit
        )
    except ValueError as exc:
        raise ValueError(f"{source}: [carriage]: {exc}") from None
    carriage = {key: _user(getattr(spec, _field(key)[0]), _field(key)[1]) for key in schema}
    provenance = {key: prov.get(_field(key)[0], "default") for key in schema}
    out = dict(raw, carriage=carriage)
    guideway = raw.get("guideway") or {}
    if isinstance(guideway, dict) and "carriage_footprint_mm" not in guideway:
        guideway = dict(guideway)
        guideway["carriage_footprint_mm"] = [round(v * 1e3, 9) for v in block.footprint]
        provenance["guideway.carriage_footprint_mm"] = (
            f"published: steel body length × block width ({block.cite})"
        )
        out["guideway"] = guideway
    return out, {"block": block.name, "preload_class": cls, "provenance": provenance}
