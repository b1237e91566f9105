"""The solvers' shared cache (dynamics.solvers.cache): bounded, least recently used first out, and
None is a result like any other (a system without classical modes is not re-examined every call)."""

from dynamics.solvers import cache


def test_least_recently_used_entry_goes_first_and_none_is_kept():
    cache.clear()
    calls = []

    def compute(value):
        def run():
            calls.append(value)
            return value

        return run

    assert cache.cached(("none",), compute(None)) is None
    assert cache.cached(("none",), compute("again")) is None
    for i in range(cache.SIZE - 1):
        cache.cached(("entry", i), compute(i))
    assert cache.size() == cache.SIZE
    cache.cached(("none",), compute("again"))  # touch: now the most recently used
    cache.cached(("entry", "new"), compute("new"))  # evicts ("entry", 0), the least recently used
    assert cache.size() == cache.SIZE
    cache.cached(("none",), compute("again"))
    cache.cached(("entry", 0), compute("zero again"))
    assert calls.count("again") == 0
    assert calls.count("zero again") == 1
    cache.clear()
    assert cache.size() == 0
