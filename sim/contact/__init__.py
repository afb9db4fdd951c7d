"""Contact mechanics shared by the closed-form fidelities (``analytic``, ``rigid``) and the Dynamixel finger.

:mod:`.layered` computes the surface compliance of a stack of elastic layers on a rigid base in the Hankel domain;
:mod:`.law` solves the frictionless contact of a rigid sphere on it (a Fredholm equation of the second kind) into
a :class:`~.law.ContactLaw`: force, contact radius and pressure against indentation, a function any caller (a
series compliance such as a finger pulp) can wrap; :mod:`.stack` turns an object at a press point into the stack
the law solves (layers, inclusions and haptic-material maps homogenised over the strained volume).
"""
