"""Independent references and numerical experiments used by the tests and benchmarks only.

The event-located reference of the clearance chain, the stability maps, the work-precision problems
and the small closed-form models: oracles that check the library, never imported by it.
"""
