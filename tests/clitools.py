"""What the command-line tests share: runs written as CSV files, and a command's stop with one line."""

from pathlib import Path


def write_csvs(runs, folder) -> list[str]:
    """Each run written as ``folder/<name>.csv`` (its :meth:`~diffship.data.Run.to_dataframe`); the paths."""
    paths = []
    for r in runs:
        p = Path(folder) / f"{r.name}.csv"
        r.to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    return paths


def stops_with_one_line(main, argv, capsys, *words) -> str:
    """A command's ``main(argv)`` ends with exit status 2 and one line ``error: ...`` holding ``words``; the line."""
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 0, (argv, err)
    for w in words:
        assert w in err, (w, err)
    return err
