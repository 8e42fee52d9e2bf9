"""`rtchannel data list|fetch|verify`: the third-party data the project can use (see `rtchannel.data_registry`)."""
from __future__ import annotations


def add_data(sub) -> None:
    """Register the `data` subcommand."""
    p = sub.add_parser("data", help="list, fetch or verify third-party data (motion capture, real images)",
                       description="Third-party data is fetched on demand from its public origin and checked "
                       "by sha256; a local mirror (RTCHANNEL_DATA_MIRROR, or a 'shared' folder beside the "
                       "checkout) is used first, then the user cache (RTCHANNEL_DATA_CACHE).")
    p.add_argument("action", choices=("list", "fetch", "verify"),
                   help="list: registered files and where they are; fetch: download what is missing; verify: "
                   "check the checksums of what is present")
    p.add_argument("patterns", nargs="*", default=["*"],
                   help="registry paths, folder prefixes or globs (default: everything), e.g. 'mocap/hdm05'")
    p.add_argument("--licences", action="store_true", help="list: group the files by licence")
    p.set_defaults(func=cmd_data)


def _selected(patterns: list[str]):
    from rtchannel.cli.common import UserError
    from rtchannel.data_registry import Entry, entries

    chosen: dict[str, Entry] = {}
    for pat in patterns:
        found = entries(pat)
        if not found:
            raise UserError(f"{pat}: no registered data file matches (rtchannel data list shows them)")
        chosen.update((e.path, e) for e in found)
    return [chosen[k] for k in sorted(chosen)]


def cmd_data(args) -> int:
    from rtchannel import data_registry as reg

    selected = _selected(args.patterns)
    if args.action == "list":
        if args.licences:
            for licence, paths in sorted(reg.licences().items()):
                mine = [p for p in paths if any(e.path == p for e in selected)]
                if mine:
                    print(f"{licence}\n  {len(mine)} files, e.g. {mine[0]}")
            return 0
        for e in selected:
            print(f"{reg.status(e):7s} {e.size / 1e3:9.1f} kB  {e.path}")
        where = reg.mirror_dir()
        print(f"mirror: {where if where else '(none)'}; cache: {reg.cache_dir()}")
        return 0
    if args.action == "fetch":
        from tqdm import tqdm

        missing = [e for e in selected if reg.status(e) == "missing"]
        for e in tqdm(missing, desc="fetching", unit="file", disable=not missing):
            reg.fetch(e.path, progress=False)
        print(f"{len(selected)} files present ({len(missing)} fetched) under {reg.cache_dir()}"
              + (f" or the mirror {reg.mirror_dir()}" if reg.mirror_dir() else ""))
        return 0
    # verify: every present file's checksum; a copy that does not match is reported, not used
    bad = []
    for e in selected:
        for root in [r for r in (reg.mirror_dir(), reg.cache_dir()) if r is not None]:
            p = root / e.path
            if p.exists() and reg.status(e) == "missing":
                bad.append(str(p))
    present = sum(reg.status(e) != "missing" for e in selected)
    print(f"{present} of {len(selected)} files present and verified; {len(bad)} with a wrong checksum")
    for p in bad:
        print(f"  checksum mismatch: {p}")
    return 1 if bad else 0
