"""One or two examples per command, shown at the end of its ``--help`` (the command's epilog).

Kept in one table, so that a command added anywhere gets its examples here (a test fails for a
command without any, parses every example against its command's options, and checks that each
fits one line of an 80-column terminal). A command's docstring holds no examples of its own.
"""

from __future__ import annotations

EXAMPLES: dict[str, tuple[str, ...]] = {
    "build": ("casadrone build build-small --out build-out",
              "casadrone build build-small --laps 3 build.rank=5 --json"),
    "codesign": ("casadrone codesign codesign-paper --out codesign-out",
                 "casadrone codesign codesign-season codesign.starts=2 --json"),
    "validate": ("casadrone validate configs problems",
                 "casadrone validate my-frame.yaml --json"),
    "trim": ("casadrone trim SY250",
             "casadrone trim HS210 --condition forward --speed 20 --solver all"),
    "linearise": ("casadrone linearise SY250 --method both",
                  "casadrone linearise SY250 alpha_deg=80 --condition forward --speed 5 --json"),
    "lqr": ("casadrone lqr SY250",
            "casadrone lqr HS210 --ensemble 50 --plot figures"),
    "export": ("casadrone export SY250 --format px4",
               "casadrone export runs/quick --candidate B --format dxf --out frame.dxf"),
    "simulate": ("casadrone simulate SY250",
                 "casadrone simulate HS210 alpha_deg=80 --integrator cvodes --json"),
    "benchmark": ("casadrone benchmark",
                  "casadrone benchmark --integrator cvodes --json"),
    "limit-lap": ("casadrone limit-lap SY250",
                  "casadrone limit-lap SY250 --track multigp-cdra-gates --plot figures"),
    "massprops": ("casadrone massprops SY250-components",
                  "casadrone massprops SY250-components lambda_a_mm=140 --json"),
    "run": ("casadrone run quick --out runs/quick",
            "casadrone run paper-run1 algorithm.generations=20 --out runs/p1 -j 8"),
    "resume": ("casadrone resume runs/quick",),
    "decide": ("casadrone decide runs/quick",
               "casadrone decide runs/quick --method extreme --objective J3 --json"),
    "compare": ("casadrone compare runs/quick",
                "casadrone compare runs/quick --reference SY250 --reference HS210 --measured"),
    "report": ("casadrone report runs/quick",
               "casadrone report runs/quick --out quick.html"),
    "fit-propulsion": ("casadrone fit-propulsion example-5in --diameter-in 5",
                       "casadrone fit-propulsion stand.csv --diameter-in 5 --part propeller"),
    "parts": ("casadrone parts --kind motor",
              "casadrone parts --file example-parts --kind pack --json"),
    "trim-study": ("casadrone trim-study SY250 --starts 5",
                   "casadrone trim-study HS210 --conditions forward:0..40/5 --json"),
}


def epilog(command: str) -> str | None:
    """The examples of ``command`` as the text ending its ``--help`` (None without any)."""
    examples = EXAMPLES.get(command)
    if not examples:
        return None
    return "Examples:\n\n" + "\n\n".join(f"  {e}" for e in examples)
