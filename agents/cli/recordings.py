"""``vrloco record`` (a policy's episodes as a Minari dataset), ``vrloco estimate`` (the
estimators on a real recording) and ``vrloco data`` (the real recordings: list, where, fetch)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def cmd_record(args: argparse.Namespace) -> int:
    from agents.learned.offline_datasets import MinariMissing, dataset_path, record_dataset

    try:
        dataset = record_dataset(
            args.task,
            args.policy,
            args.minari,
            technique=args.technique,
            episodes=args.episodes,
            seed=args.seed,
            max_episode_steps=args.max_episode_steps,
            force=args.force,
            progress=True,
        )
    except ValueError as err:  # an unknown policy or technique, a bad id: one line
        print(f"vrloco record: {err}", file=sys.stderr)
        return 2
    except (FileExistsError, MinariMissing) as err:  # the dataset exists; no Minari: one line
        print(f"vrloco record: {err}", file=sys.stderr)
        return 1
    n = dataset.total_episodes
    print(
        f"wrote {n} episode{'s' * (n != 1)} ({dataset.total_steps} steps) to Minari "
        f"dataset {args.minari} at {dataset_path(args.minari)}; read it with "
        f"minari.load_dataset({args.minari!r})"
    )
    return 0


def cmd_estimate(args: argparse.Namespace) -> int:
    from agents.recordings.estimate import estimate_recording
    from agents.recordings.units import Units

    try:
        units = Units(time=args.time_unit, acc=args.acc_unit, gyro=args.gyro_unit)
        result = estimate_recording(
            Path(args.path), Path(args.out), args.step_length, offline=args.offline, units=units
        )
    except ValueError as err:  # a malformed recording: one clear line, no traceback
        print(f"vrloco estimate: {err}", file=sys.stderr)
        return 2
    print(json.dumps(result, indent=2))
    return 0


def cmd_data(args: argparse.Namespace) -> int:
    from agents.recordings import data

    prog = f"vrloco data {args.data_command}"
    try:
        if args.data_command == "list":
            env = data.data_folder()
            print(f"cache (VRLOCO_CACHE): {data.cache_folder()}")
            print(f"VRLOCO_DATA: {env if env is not None else 'not set'}")
            for name, ds in data.DATASETS.items():
                n = len(ds.files)
                size = f", {n} file{'s' * (n > 1)}, {sum(f.size for f in ds.files) / 1e6:.1f} MB"
                where = data.located(name)
                if where is not None:
                    state = f"in {where[0]}: {where[1] / ds.path}"
                elif ds.fetchable:
                    state = f"absent: `vrloco data fetch {name}`"
                else:
                    state = f"absent: {ds.why_not_fetched}"
                print(f"{name:<12} {ds.title}{size if ds.files else ''}; licence {ds.licence}")
                print(f"{'':<12} {state}")
                print(f"{'':<12} cite: {ds.citation}")
            return 0
        if args.data_command == "where":
            print(data.data_path(args.name) if args.name else data.cache_folder())
            return 0
        sets = [data.get_dataset(name) for name in args.names]  # every name checked first
        for ds in sets:
            if not ds.fetchable:
                raise ValueError(f"{ds.name}: {ds.why_not_fetched}")
        data.mirror_url(args.url, origin="--url")
        for ds in sets:
            path = data.fetch(
                ds.name,
                base_url=args.url,
                progressbar=sys.stderr.isatty(),
                report=lambda line: print(f"  {line}"),
            )
            print(f"{ds.name}: {path}")
            print(f"  licence {ds.licence}; cite: {ds.citation}; source: {ds.source}")
    except ValueError as err:  # an unknown name, a set that is not downloadable, a bad URL
        print(f"{prog}: {err}", file=sys.stderr)
        return 2
    except (data.DataMissing, data.FetchError) as err:  # absent, or a failed download: one line
        print(f"{prog}: {err}", file=sys.stderr)
        return 1
    return 0
