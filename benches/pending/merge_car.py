import json, sys
sys.path.insert(0, 'benches')
from bench_paper import summary, group_key
old = json.load(open('benches/results/paper_full_car.json'))
vib = json.load(open('/tmp/exp/vib_e.json'))['rows']
assert len(vib) == 6 and all(r.get('simulation') for r in vib)
rows = [r for r in old['rows'] if not r.get('simulation')] + vib
groups = list(dict.fromkeys(group_key(r) for r in rows))
out = {k: v for k, v in old.items() if k not in ('rows', 'summary', 'note')}
out['note'] = sys.argv[1]
out['rows'] = rows
out['summary'] = {g: summary([r for r in rows if group_key(r) == g]) for g in groups} | {'all': summary(rows)}
open('benches/results/paper_full_car.json', 'w').write(json.dumps(out, indent=2) + '\n')
print(len(rows), list(out.keys()))
