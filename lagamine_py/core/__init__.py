"""The bottom layer: what every other part of lagamine_py may import, and which imports nothing
of lagamine_py itself.

* :mod:`.params`  -- declared parameters (:class:`~.params.Param`), their validation, Fortran
  numbers, did-you-mean;
* :mod:`.errors`  -- the typed failures: a cut-back request from a law or an element, the
  convergence failures of Newton, a singular matrix;
* :mod:`.status`  -- the contact status codes and names;
* :mod:`.tensors` -- small tensor helpers shared by elements, laws and writers (isotropic
  elasticity, von Mises, 2x2 algebra, the right normal of a tangent);
* :mod:`.exits`   -- the exit statuses of the command line;
* :mod:`.threads` -- the thread policy of the numerical libraries.
"""
