set terminal pngcairo size 900,540
set output 'models/pretrained/report/rollout_pmd_a.png.tmp'
set title 'PMD_a over rollout frames'
set xlabel 'frame'
set ylabel 'PMD_a (cm)'
set grid
set key top left
set datafile missing 'NaN'
plot 'models/pretrained/report/rollout_0.dat' using 1:2 with lines lw 2 title 'Apparel module, GT mask + weights, held-out characters', 'models/pretrained/report/rollout_1.dat' using 1:2 with lines lw 2 title 'Body + apparel modules, held-out characters', 'models/pretrained/report/rollout_2.dat' using 1:2 with lines lw 2 title 'Full model, held-out characters', 'models/pretrained/report/rollout_3.dat' using 1:2 with lines lw 2 title 'hold_offset rule (no network), held-out characters', 'models/pretrained/report/rollout_4.dat' using 1:2 with lines lw 2 title 'Skinning baseline (LBS, GT body weights), held-out characters', 'models/pretrained/report/rollout_5.dat' using 1:2 with lines lw 2 title 'Apparel module, GT mask + weights, held-out clips', 'models/pretrained/report/rollout_6.dat' using 1:2 with lines lw 2 title 'Body + apparel modules, held-out clips', 'models/pretrained/report/rollout_7.dat' using 1:2 with lines lw 2 title 'Full model, held-out clips', 'models/pretrained/report/rollout_8.dat' using 1:2 with lines lw 2 title 'hold_offset rule (no network), held-out clips', 'models/pretrained/report/rollout_9.dat' using 1:2 with lines lw 2 title 'Skinning baseline (LBS, GT body weights), held-out clips'
unset output
