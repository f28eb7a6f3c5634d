"""Run the benchmark suite: ``python benchmarks/run.py [--quick] [--only NAME]... [--json PATH]``.

The same as ``diracvi bench``; the code lives in the installed package (``diracvi.bench``)
so that the command works after a plain ``pip install .``. Method and results:
``benchmarks/README.md``.
"""

from diracvi.bench import main

if __name__ == "__main__":
    main()
