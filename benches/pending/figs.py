import json, statistics as st, sys
rows = json.load(open(sys.argv[1]))['rows']
for sc in ['test1', 'test2', 'test3', 'urban']:
    R = [r for r in rows if r['scenario'] == sc]
    if not R: continue
    a = [r['sar-min+af'] for r in R]; s = [r['sar-min'] for r in R]
    e = [x['reflector_error_max_cm'] for x in a]
    far = [r['entropy_far']['vs_truth_pct']['sar-min+af'] for r in R]
    d = [r['af_track_scale_pct'] - r['sarmin_track_scale_pct'] for r in R if r['af_track_scale_pct']]
    print(f"{sc} ({len(R)}): af median/max {st.median(e):.2f}/{max(e):.2f}; within {sum(x['within_2cm_1db'] for x in a)} (sar-min {sum(x['within_2cm_1db'] for x in s)}); "
          f"peak af {max(x['peak_loss_max_db'] for x in a):+.2f} sarmin {max(x['peak_loss_max_db'] for x in s):+.2f}; far median {st.median(far):+.2f}, within0.2 {sum(abs(f) <= 0.2 for f in far)}; "
          f"rpe max {max(x['rpe_1m_across_mm'] for x in a):.2f}; scale-err n={len(d)} mean {st.fmean(d) if d else 0:+.4f} rms {(st.fmean([x*x for x in d])**.5) if d else 0:.4f}; misses {[r['seed'] for r, x in zip(R, a) if not x['within_2cm_1db']]}")
