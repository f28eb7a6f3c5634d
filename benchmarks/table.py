"""Print the Markdown table of a ``diracvi bench --json PATH`` file (for README.md).

python benchmarks/table.py bench.json
"""

import json
import sys
from pathlib import Path

from diracvi.bench.report import markdown

if __name__ == "__main__":
    print(markdown(json.loads(Path(sys.argv[1]).read_text(encoding="utf-8"))))
