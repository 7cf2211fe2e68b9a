"""Progress bars: rates and ETAs count only the work done now."""


def test_progress_rate_ignores_runs_done_before():
    import time

    from dpcbench.bench.core.progress import progress_bar

    bar = progress_bar(total=100, initial=90, quiet=False)
    time.sleep(0.2)
    bar.update(1)
    rate = bar.format_dict["rate"]
    bar.close()
    assert bar.n == 91 and rate is not None and rate < 20  # one run in 0.2 s, not 91
