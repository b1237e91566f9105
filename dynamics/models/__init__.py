"""The chain models: one topology, the linear and clearance chains, the machine on its wheels,
friction, damping forms, modal reduction and the 2012 report's replica."""
