"""Write benches/results/paper_full_level.json from the branch's runs (run in the repo root with benches on path)."""
import json, sys
sys.path.insert(0, 'benches')
from bench_paper import summary, group_key
old = json.load(open('benches/results/paper_full_level.json'))
t123 = json.load(open('/tmp/exp/pfl_e123.json'))['rows']
urban = json.load(open('/tmp/exp/pfl_d_urban.json'))['rows']
rows = sorted(t123, key=lambda r: (r['seed'], r['scenario'])) + urban
assert len(rows) == 40 and len({(r['scenario'], r['seed']) for r in rows}) == 40
groups = list(dict.fromkeys(group_key(r) for r in rows))
out = {k: old[k] for k in ('benchmark', 'methods', 'dynamics', 'components')}
out['note'] = sys.argv[1]
out['rows'] = rows
out['summary'] = {g: summary([r for r in rows if group_key(r) == g]) for g in groups} | {'all': summary(rows)}
open('benches/results/paper_full_level.json', 'w').write(json.dumps(out, indent=2) + '\n')
print(json.dumps(out['summary']['all'], indent=1)[:800])
