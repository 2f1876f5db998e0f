"""`python -m bench`: the registered benches' make targets, in run order (`make bench` loops
over them)."""
from bench import BENCHES

if __name__ == "__main__":
    print(" ".join(name.replace("_", "-") for name in BENCHES))
