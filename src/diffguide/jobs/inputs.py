"""The measurement files' reading settings of the jobs: profiles (``--profile``) with their
``--profile-set`` items (:mod:`diffguide.io.profiles`)."""


def profile_sets(items, profiles=()) -> dict:
    """``--profile-set [PROFILE:]KEY=VALUE`` items as ``{profile or None: {key: value}}``
    (numbers read as numbers). A ``PROFILE:`` prefix binds the setting to the files read
    through that ``--profile``; without it, the setting needs a single profile (``profiles``:
    the distinct ``--profile`` values other than ``auto``), so that a setting meant for one
    file never lands on another's."""
    out: dict = {}
    for item in items or []:
        left, sep, value = item.partition("=")
        prof, colon, key = left.rpartition(":")
        if not sep or not key.strip():
            raise ValueError(f"--profile-set {item!r}: expected [PROFILE:]KEY=VALUE (a "
                             "[reading] key of the profile, e.g. point=P5 or exx:point=P5)")
        target = prof.strip() if colon else None
        if target is not None and target not in profiles:
            raise ValueError(f"--profile-set {item!r}: {target!r} is not one of the --profile "
                             f"options ({', '.join(profiles) or 'none'})")
        if target is None and len(profiles) > 1:
            raise ValueError(
                f"--profile-set {item!r}: the files are read through {len(profiles)} profiles "
                f"({', '.join(profiles)}); say which one it is for: --profile-set "
                f"{profiles[-1]}:{left.strip()}={value.strip()}")
        try:
            parsed: float | str = float(value)
        except ValueError:
            parsed = value.strip()
        out.setdefault(target, {})[key.strip()] = parsed
    return out


def load_profile_args(args, files):
    """The profile of each file in ``files`` (``--profile``, once or once per file, with
    ``--profile-set`` applied; ``None``: a canonical layout)."""
    from ..io.profiles import check_profile, load_profile

    names = args.profile or []
    if not names:
        if args.profile_set:
            raise ValueError("--profile-set needs --profile")
        return [None] * len(files)
    if len(names) not in (1, len(files)):
        raise ValueError(f"{len(names)} --profile options for {len(files)} files (allowed: one "
                         "for every file, or one per file in their order)")
    used = [n for n in dict.fromkeys(names) if n != "auto"]
    sets = profile_sets(args.profile_set, used)
    loaded = {}
    for name in dict.fromkeys(names):
        if name == "auto":
            loaded[name] = None
            continue
        prof = load_profile(name)
        mine = {**sets.get(None, {}), **sets.get(name, {})}
        if mine:
            prof.setdefault("reading", {}).update(mine)
            check_profile(prof, f"{prof['_source']} with --profile-set")
        loaded[name] = prof
    return [loaded[n] for n in (names * len(files) if len(names) == 1 else names)]
